# signorini: set-up, demo, tests and batch studies. `make demo` and `make test` set everything up first.
SHELL := /bin/bash
VENV := .venv
PY := $(VENV)/bin/python
SIGNORINI := $(VENV)/bin/signorini
STAMP := $(VENV)/.setup-done
APT_PACKAGES := python3-dolfinx-real python3-gmsh python3-h5py python3-yaml python3-matplotlib python3-wheel \
                python3-pytest python3-pytest-mpi python3-sympy python3-meshio python3-venv openmpi-bin \
                texlive-latex-base texlive-latex-recommended  # pdflatex, amsmath, graphicx; booktabs
NP ?= 2
# Open MPI refuses to run as root without these; harmless for other users.
export OMPI_ALLOW_RUN_AS_ROOT := 1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM := 1
export OMPI_MCA_rmaps_base_oversubscribe := 1
MPIRUN := mpirun -n $(NP)
CONFIG ?= configs/demo.yaml
CONFIGS := $(shell find configs -path configs/maps -prune -o -name '*.yaml' -print | sort)  # maps: `make maps`
PAPER_CONFIGS := $(sort $(wildcard configs/paper/*.yaml)) configs/gmsh/l-shape-corner.yaml  # and the corner solution
PAPER_RESULTS := results/paper

.PHONY: setup demo test test-serial test-mpi test-fast run studies verify meshes geometries clean

setup: $(STAMP)

$(STAMP): pyproject.toml
	@bash .ci/install-system-packages $(APT_PACKAGES)
	/usr/bin/python3 -m venv --system-site-packages $(VENV)
	$(PY) -m pip install --quiet --no-build-isolation -e .
	@touch $@

demo: setup
	$(SIGNORINI) run configs/demo.yaml --force

test: setup test-mpi test-serial

test-serial: setup
	SIGNORINI_REQUIRE_LATEX=1 $(PY) -m pytest -m "not mpi" -q

# one mpirun per test folder: a 2-rank test that leaves the ranks' collective calls out of step (or PETSc state
# behind) then shows in its own folder, not as a hang of an unrelated test later in the same processes; a folder
# without MPI tests is passed by (mpirun would print its abort banner for pytest's exit 5, which is no failure)
test-mpi: setup
	@failed=""; for folder in $$(find tests -mindepth 1 -maxdepth 1 -type d ! -name bad_input ! -name '__*' | sort); do \
	  grep -rqE 'mark\.mpi' --include='*.py' $$folder || continue; \
	  echo "== $$folder"; timeout 600 $(MPIRUN) $(PY) -m pytest --with-mpi -m mpi -q -p no:cacheprovider $$folder; \
	  status=$$?; if [ $$status -ne 0 ] && [ $$status -ne 5 ]; then failed="$$failed $$folder"; fi; done; \
	  if [ -n "$$failed" ]; then echo "MPI tests failed in:$$failed"; exit 1; fi

# the inner loop (< 30 s): the tests marked `fast`; `make test` stays the full suite that CI runs
test-fast: setup
	$(PY) -m pytest -m "fast and not mpi" -q -p no:cacheprovider

run: setup
	$(SIGNORINI) run $(CONFIG) --force

# --- batch runs: one target per config -------------------------------------------------------------
# A run's record is a stamp results/.make/<set>/<config>.status holding its exit status; it depends on the
# config file and the package sources, so `make -j2 studies` runs two studies side by side and a second
# `make studies` re-runs only the configs (or all of them after a package change) that changed. Exit 1
# (a level did not converge, an `expect:` rate missed) is recorded, not fatal: the page targets name those
# studies after writing their page. --output-sync keeps each study's lines together under -j.
PACKAGE := pyproject.toml $(wildcard signorini_cli/*.py signorini_cli/*/*.py)
MADE := results/.make
MAKEFLAGS += --output-sync=target
# $(call run,config,extra arguments,launcher): run it, record its status (0 or 1; anything else fails)
define run
@mkdir -p $(dir $@)
@echo "== $(1)"
@$(3) $(SIGNORINI) run $(1) --force $(2); status=$$?; \
  if [ $$status -gt 1 ]; then exit $$status; fi; echo $$status > $@
endef
# $(call missed,stamps): fail naming the studies whose status is not 0
define missed
@missed=$$(grep -L '^0$$' $(1) | sed 's|^$(MADE)/[^/]*/||; s|\.status$$||' | tr '\n' ' '); \
  if [ -n "$$missed" ]; then echo "levels not converged or expectations not met: $$missed"; exit 1; fi
endef

STUDY_STAMPS := $(CONFIGS:%=$(MADE)/studies/%.status)
studies: $(STUDY_STAMPS)
$(MADE)/studies/%.status: % $(PACKAGE) | $(STAMP)
	$(call run,$<)

# The configs/paper studies into results/paper, then docs/verification.md from their results (the page
# is written even when an `expect:` block is missed; the target fails afterwards, naming the studies).
PAPER_STAMPS := $(PAPER_CONFIGS:%=$(MADE)/paper/%.status)
verify: docs/verification.md
	$(call missed,$(PAPER_STAMPS))
$(MADE)/paper/%.status: % $(PACKAGE) | $(STAMP)
	$(call run,$<,--output $(PAPER_RESULTS))
docs/verification.md: $(PAPER_STAMPS) scripts/verification_page.py scripts/provenance.py
	@mkdir -p docs
	$(PY) scripts/verification_page.py $(PAPER_RESULTS) $(PAPER_CONFIGS) > $@.tmp
	@mv $@.tmp $@; echo "wrote $@"

# gmsh meshes of every config's geometry levels into meshes/cache/ (studies also fill it on demand)
meshes: setup
	$(PY) -m signorini_cli.meshing.geometries $(CONFIGS)

# configs/gmsh studies serially and on $(NP) ranks, then docs/geometries.md from their tables
GMSH_CONFIGS := $(shell find configs/gmsh -name '*.yaml' | sort)
GMSH_STAMPS := $(GMSH_CONFIGS:%=$(MADE)/geometries-serial/%.status) $(GMSH_CONFIGS:%=$(MADE)/geometries-mpi/%.status)
geometries: docs/geometries.md
$(MADE)/geometries-serial/%.status: % $(PACKAGE) | $(STAMP)
	$(call run,$<,--output results/geometries/serial)
$(MADE)/geometries-mpi/%.status: % $(PACKAGE) | $(STAMP)
	$(call run,$<,--output results/geometries/mpi,$(MPIRUN))
docs/geometries.md: $(GMSH_STAMPS) scripts/geometries_page.py scripts/provenance.py
	$(PY) scripts/geometries_page.py results/geometries/serial results/geometries/mpi $(GMSH_CONFIGS) > $@.tmp
	@mv $@.tmp $@; echo "wrote $@"

clean:
	rm -rf results build *.egg-info .pytest_cache
	find . -name __pycache__ -prune -exec rm -rf {} +

# The Signorini limit (docs/limit.md): run configs/limit/, then write the page and its plot from the runs.
LIMIT_CONFIGS := $(sort $(wildcard configs/limit/*.yaml))
LIMIT_STAMPS := $(LIMIT_CONFIGS:%=$(MADE)/limit/%.status)
.PHONY: limit
limit: docs/limit.md
	$(call missed,$(LIMIT_STAMPS))
$(MADE)/limit/%.status: % $(PACKAGE) | $(STAMP)
	$(call run,$<)
docs/limit.md: $(LIMIT_STAMPS) scripts/limit_page.py scripts/cells.py scripts/provenance.py
	$(PY) scripts/limit_page.py $(LIMIT_CONFIGS) --out $@

# Nitsche's method beside the penalty model (docs/methods.md): run configs/methods/ (Nitsche θ = 1, 0, -1, the
# penalty at ε = h^p and a map over problem.method, all on the manufactured u_S), then the page from the runs. The
# map's point θ = 1, γ0 = 1 lies outside the proof's hypothesis (γ0 small enough) and fails by design: the map's
# status is not a gate.
METHOD_CONFIGS := $(sort $(wildcard configs/methods/*.yaml))
METHOD_STAMPS := $(METHOD_CONFIGS:%=$(MADE)/methods/%.status)
.PHONY: methods
methods: docs/methods.md
	$(call missed,$(filter-out %/map-method.yaml.status,$(METHOD_STAMPS)))
$(MADE)/methods/%.status: % $(PACKAGE) | $(STAMP)
	$(call run,$<,--quiet)
docs/methods.md: $(METHOD_STAMPS) scripts/methods_page.py scripts/cells.py scripts/provenance.py
	$(PY) scripts/methods_page.py $(METHOD_CONFIGS) --out $@

# P2 against P1 (docs/elements.md): run configs/elements/, then write the page from the runs.
ELEMENT_CONFIGS := $(sort $(wildcard configs/elements/*.yaml))
ELEMENT_STAMPS := $(ELEMENT_CONFIGS:%=$(MADE)/elements/%.status)
.PHONY: elements
elements: docs/elements.md
	$(call missed,$(ELEMENT_STAMPS))
$(MADE)/elements/%.status: % $(PACKAGE) | $(STAMP)
	$(call run,$<)
docs/elements.md: $(ELEMENT_STAMPS) scripts/elements_page.py scripts/cells.py scripts/provenance.py
	$(PY) scripts/elements_page.py $(ELEMENT_CONFIGS) --out $@

.PHONY: stiff
# the stiff suite, the regular studies with strategy auto, a delta sweep and a conditioning sweep -> docs/stability.md
# (one script runs them all: re-run when it, a config or the package changed)
stiff: docs/stability.md
docs/stability.md: scripts/stability.py scripts/provenance.py $(CONFIGS) $(PACKAGE) | $(STAMP)
	$(PY) scripts/stability.py

.PHONY: bench bench-check stale-pages
# bench/configs/ serially, on $(NP) ranks and with three start strategies, the whole default run against the
# tutorial-style scripts, start-up -> bench/results.md, .csv and bench/targets.json (what bench-check compares with)
bench: bench/results.md
bench/results.md: scripts/bench.py scripts/bench_check.py scripts/tutorial_baseline.py scripts/provenance.py \
                  $(wildcard bench/configs/*.yaml) $(PACKAGE) | $(STAMP)
	$(PY) scripts/bench.py
# the short part of the bench (< 3 min): fails when a target regressed against bench/targets.json; run it before
# a change to solve/, problems/, studies/ or meshing/ is handed on
bench-check: setup
	$(PY) scripts/bench_check.py
# the generated pages (a "Generated by" line) made by a revision older than the package's last change; fails if any
stale-pages:
	@$(PY) scripts/stale_pages.py

.PHONY: precision
# every configs/**/*.yaml (first 4 levels in 2-D, 3 in 3-D) at default settings, with a tight
# solve and with solver.polish=0 -> docs/precision.md; fails when an error entry moves by > 1e-6
precision: docs/precision.md
docs/precision.md: scripts/precision.py scripts/provenance.py $(CONFIGS) $(PACKAGE) | $(STAMP)
	$(PY) scripts/precision.py --page $@

.PHONY: reference
# the config reference, generated from the config's dataclasses (tests/scripts/test_config_reference.py keeps it current)
reference: docs/reference/config.md
docs/reference/config.md: scripts/config_reference.py $(PACKAGE) | $(STAMP)
	$(PY) scripts/config_reference.py > $@.tmp
	@mv $@.tmp $@; echo "wrote $@"

.PHONY: results-format
# docs/results-format.md from the writer's own descriptions and the study.h5 of a two-level demo run
results-format: docs/results-format.md
docs/results-format.md: scripts/results_format_page.py scripts/provenance.py signorini_cli/record/h5.py $(PACKAGE) | $(STAMP)
	$(PY) scripts/results_format_page.py > $@.tmp
	@mv $@.tmp $@; echo "wrote $@"

.PHONY: elasticity bench-elasticity
# Linear elasticity (docs/elasticity.md): configs/elasticity's manufactured studies, the stiff case and the Hertz
# benchmark (h -> 0 and eps -> 0), run by the script that writes the page from them
ELASTIC_CONFIGS := $(sort $(wildcard configs/elasticity/*.yaml))
elasticity: docs/elasticity.md
docs/elasticity.md: scripts/elasticity_page.py scripts/provenance.py $(ELASTIC_CONFIGS) $(PACKAGE) | $(STAMP)
	$(PY) scripts/elasticity_page.py --out $@
# the elastic section of bench/results.md: Newton time against the linear floor, 2-D up to N = 256, 3-D 32^3
bench-elasticity: setup
	$(PY) scripts/elasticity_page.py --bench

# Rate maps (docs/maps.md): configs/maps/ on $(NP) ranks (groups of one rank take the points in turn), then
# the page and its figures from the maps' folders.
MAP_CONFIGS := $(sort $(wildcard configs/maps/*.yaml))
MAP_STAMPS := $(MAP_CONFIGS:%=$(MADE)/maps/%.status)
.PHONY: maps bench-maps
maps: docs/maps.md
	$(call missed,$(MAP_STAMPS))
$(MADE)/maps/%.status: % $(PACKAGE) | $(STAMP)
	$(call run,$<,--quiet,$(MPIRUN))
docs/maps.md: $(MAP_STAMPS) scripts/maps_page.py scripts/provenance.py
	$(PY) scripts/maps_page.py $(MAP_CONFIGS) --out $@

# only the map section of the bench (bench/maps.md, bench/maps.csv)
bench-maps: setup
	$(PY) scripts/bench.py --maps
