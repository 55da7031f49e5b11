# signorini: set-up, demo, tests and batch studies. `make demo` and `make test` set everything up first.
SHELL := /bin/bash
VENV := .venv
PY := $(VENV)/bin/python
SIGNORINI := $(VENV)/bin/signorini
STAMP := $(VENV)/.setup-done
APT_PACKAGES := python3-dolfinx-real python3-gmsh python3-h5py python3-yaml python3-matplotlib python3-wheel \
                python3-pytest python3-pytest-mpi python3-sympy python3-venv openmpi-bin
NP ?= 2
# Open MPI refuses to run as root without these; harmless for other users.
export OMPI_ALLOW_RUN_AS_ROOT := 1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM := 1
export OMPI_MCA_rmaps_base_oversubscribe := 1
MPIRUN := mpirun -n $(NP)
CONFIG ?= configs/demo.yaml
CONFIGS := $(shell find configs -name '*.yaml' | sort)
PAPER_CONFIGS := $(sort $(wildcard configs/paper/*.yaml))
PAPER_RESULTS := results/paper

.PHONY: setup demo test test-serial test-mpi run studies verify meshes geometries clean

setup: $(STAMP)

$(STAMP): pyproject.toml
	@bash .ci/install-system-packages $(APT_PACKAGES)
	/usr/bin/python3 -m venv --system-site-packages $(VENV)
	$(PY) -m pip install --quiet --no-build-isolation -e .
	@touch $@

demo: setup
	$(SIGNORINI) run configs/demo.yaml --force

test: setup test-serial test-mpi

test-serial: setup
	$(PY) -m pytest -m "not mpi" -q

test-mpi: setup
	$(MPIRUN) $(PY) -m pytest --with-mpi -m mpi -q -p no:cacheprovider

run: setup
	$(SIGNORINI) run $(CONFIG) --force

studies: setup
	@set -e; for c in $(CONFIGS); do echo "== $$c"; $(SIGNORINI) run $$c --force || test $$? -eq 1; done

# The configs/paper studies, then docs/verification.md from their results (page written even when an
# `expect:` block is missed; the target fails afterwards, naming the studies).
verify: setup
	@set -e; missed=""; for c in $(PAPER_CONFIGS); do echo "== $$c"; \
	  $(SIGNORINI) run $$c --force --output $(PAPER_RESULTS) || { test $$? -eq 1; missed="$$missed $$c"; }; done; \
	mkdir -p docs; $(PY) scripts/verification_page.py $(PAPER_RESULTS) $(PAPER_CONFIGS) > docs/verification.md.tmp; \
	mv docs/verification.md.tmp docs/verification.md; echo "wrote docs/verification.md"; \
	if [ -n "$$missed" ]; then echo "expectations not met or levels not converged:$$missed"; exit 1; fi

# gmsh meshes of every config's geometry levels into meshes/cache/ (studies also fill it on demand)
meshes: setup
	$(PY) -m signorini_cli.geometries $(CONFIGS)

# configs/gmsh studies serially and on $(NP) ranks, then docs/geometries.md from their tables
GMSH_CONFIGS := $(shell find configs/gmsh -name '*.yaml' | sort)
geometries: setup
	@set -e; for c in $(GMSH_CONFIGS); do echo "== $$c"; \
	  $(SIGNORINI) run $$c --force --output results/geometries/serial || test $$? -eq 1; \
	  $(MPIRUN) $(SIGNORINI) run $$c --force --output results/geometries/mpi > /dev/null || test $$? -eq 1; done
	$(PY) scripts/geometries_page.py results/geometries/serial results/geometries/mpi $(GMSH_CONFIGS) > docs/geometries.md

clean:
	rm -rf results build *.egg-info .pytest_cache
	find . -name __pycache__ -prune -exec rm -rf {} +

# The Signorini limit (docs/limit.md): run configs/limit/, then write the page and its plot from the runs.
LIMIT_CONFIGS := $(sort $(wildcard configs/limit/*.yaml))
.PHONY: limit
limit: setup
	@set -e; missed=""; for c in $(LIMIT_CONFIGS); do echo "== $$c"; \
	  $(SIGNORINI) run $$c --force || { test $$? -eq 1; missed="$$missed $$c"; }; done; \
	$(PY) scripts/limit_page.py $(LIMIT_CONFIGS) --out docs/limit.md; \
	if [ -n "$$missed" ]; then echo "levels not converged or expectations not met:$$missed"; exit 1; fi

.PHONY: stiff
# the stiff suite, the regular studies with strategy auto, a delta sweep and a conditioning sweep -> docs/stability.md
stiff: setup
	$(PY) scripts/stability.py

.PHONY: bench
# issue 6: bench/configs/ serially, on $(NP) ranks and with three start strategies -> bench/results.md, .csv
bench: setup
	$(PY) scripts/bench.py

.PHONY: precision
# issue 17 item 5: every configs/**/*.yaml (first 4 levels in 2-D, 3 in 3-D) at default settings, with a tight
# solve and with solver.polish=0 -> results/precision/precision.md; fails when an error entry moves by > 1e-6
precision: setup
	$(PY) scripts/precision.py
