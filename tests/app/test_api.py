"""The Python API (docs/api.md): load a config from a file or a mapping, run it without files, a callback
that sees each level's u_h; the page's example runs as written and prints what the page says."""
import re
import runpy
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import ufl
from mpi4py import MPI

from signorini_cli import config, load, run
from signorini_cli.problems import measure
from signorini_cli.record import results
from conftest import U_SIGNORINI, merge

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
WORLD = [pytest.param(MPI.COMM_SELF, id="serial"), pytest.param(MPI.COMM_WORLD, id="world", marks=pytest.mark.mpi)]


@pytest.mark.fast
def test_import_loads_no_dolfinx():
    """`signorini --version` stays fast: the package's import reaches for load and run only on use."""
    code = "import sys, signorini_cli; print('dolfinx' in sys.modules, 'petsc4py' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False"]


@pytest.mark.fast
def test_load_file_and_mapping_with_overrides(raw_config, tmp_path):
    from_file = load(ROOT / "configs" / "demo.yaml", mesh__refinements=[4, 8], epsilon__theta=0.5)
    assert from_file.mesh.refinements == (4, 8) and from_file.epsilon.theta == 0.5 and from_file.study == "demo"
    from_mapping = load(raw_config, **{"alpha": 3.0, "output.dir": str(tmp_path)})
    assert from_mapping.alpha == 3.0 and from_mapping.output_dir == tmp_path / "t"
    assert raw_config["alpha"] == 2.0  # the caller's mapping is left as it was


@pytest.mark.fast
def test_load_bad_input_names_the_key(raw_config):
    with pytest.raises(config.ConfigError) as err:
        load(raw_config, epsilon__theta=-1)
    assert err.value.path == "epsilon.theta"


@pytest.mark.parametrize("comm", WORLD)
def test_run_passes_each_level_u_h_and_writes_nothing(raw_config, tmp_path, comm):
    """The callback's u_h is the level's solution: its L2 error, measured again in the callback, is the
    table's (the same integral, by the error rule's default degree here and by the degree the data need in
    the table: observed 3.5e-9 relative apart on N = 4, where another level's u_h would be O(1) off); no file
    is written without write=True."""
    cfg = load(raw_config, output__dir=str(tmp_path / "results"))
    seen = []

    def on_level(level, u_h, scene):
        x = ufl.SpatialCoordinate(u_h.function_space.mesh)
        u_exact = ufl.sin(2 * np.pi * x[0]) * (1 - x[1]) ** 2
        seen.append((level.n, measure.errors(u_h, u_exact, level.h, scene.error_degree)["L2"]))

    study = run(cfg, on_level=on_level, comm=comm)
    assert [n for n, _ in seen] == [row["N"] for row in study.rows] == [4, 8]
    assert [l2 for _, l2 in seen] == pytest.approx([row["L2"] for row in study.rows], rel=1e-7)
    assert list(study.rows[0])[:12] == ["level", "N", "h", "dofs", "epsilon", "converged", "newton_its", "L2",
                                        "rate_L2", "H1", "rate_H1", "time_s"]
    assert study.summary is not None and not (tmp_path / "results").exists()


def test_run_writes_when_asked(raw_config, tmp_path):
    """The record `signorini run` keeps: every level's row with the time its writing took, status complete."""
    cfg = load(raw_config, output__dir=str(tmp_path))
    study = run(cfg, comm=MPI.COMM_SELF, write=True)
    assert (tmp_path / "t" / "rates.csv").read_text().startswith("level,N,h,dofs,epsilon,converged,newton_its,L2")
    assert (tmp_path / "t" / "status.txt").read_text() == "complete\n" and study.converged and study.met
    written = results.load(tmp_path / "t")
    assert all(row["t_output"] > 0 for row in written.rows)
    assert [row["L2"] for row in written.rows] == [row["L2"] for row in study.rows]


def page_examples():
    """docs/api.md's examples: each python block with the text block that follows it."""
    text = (DOCS / "api.md").read_text()
    return list(zip(re.findall(r"```python\n(.*?)```", text, flags=re.S), re.findall(r"```text\n(.*?)```", text,
                                                                                       flags=re.S)))


def check_page_example(tmp_path, monkeypatch, capsys, k):
    """docs/api.md's k-th example, run from the repository's folder, prints the page's lines (on rank 0)."""
    example, expected = page_examples()[k]
    script = tmp_path / "example.py"
    script.write_text(example)
    monkeypatch.chdir(ROOT)
    runpy.run_path(str(script), run_name="__main__")
    assert capsys.readouterr().out == (expected if MPI.COMM_WORLD.rank == 0 else "")


EXAMPLES = [pytest.param(0, id="levels"), pytest.param(1, id="notebook")]


@pytest.mark.parametrize("k", EXAMPLES)
def test_api_page_example(tmp_path, monkeypatch, capsys, k):
    check_page_example(tmp_path, monkeypatch, capsys, k)


@pytest.mark.mpi
@pytest.mark.parametrize("k", EXAMPLES)
def test_api_page_example_parallel(tmp_path, monkeypatch, capsys, k):
    assert MPI.COMM_WORLD.size == 2
    check_page_example(tmp_path, monkeypatch, capsys, k)


def test_notebook_additions(raw_config, tmp_path):
    """Scene, columns, write_fields and report: what the notebook session uses, checked on their values."""
    scenes = []
    result = run(load(raw_config, output__dir=str(tmp_path)), comm=MPI.COMM_SELF,
                 on_level=lambda level, u_h, scene: scenes.append((level.eps, scene.pressure.x.array.max())))
    assert len(scenes) == 2 and all(p > 0 for _, p in scenes)  # the manufactured u > 0 somewhere on Γ_C
    columns = result.columns()
    assert list(columns["N"]) == [4, 8] and np.isnan(columns["rate_L2"][0]) and columns["L2"].dtype == float
    assert len(repr(result)) < 120 and repr(result).startswith("Result('t': refinement, 2 rows")
    path = result.write_fields(tmp_path / "u.xdmf")
    assert path.exists() and "boundary" in path.read_text() and (tmp_path / "u.h5").exists()
    written = result.report(tmp_path / "report", plots=False)
    assert {p.name for p in written} == {"rates.md", "rates.tex", "verdict.tex"}


def test_run_passes_u_h_of_a_signorini_study(raw_config, tmp_path):
    """The VI's levels are passed too, each with its own P1 solution."""
    raw = merge(raw_config, {"study_type": "signorini", "alpha": None, "epsilon": None,
                             "problem": {"exact": U_SIGNORINI, "exact_solves": "signorini"}})
    seen = []
    study = run(load(raw, output__dir=str(tmp_path)), comm=MPI.COMM_SELF,
                on_level=lambda level, u_h: seen.append((level.n, u_h.function_space.dofmap.index_map.size_global)))
    assert seen == [(4, 25), (8, 81)] and [row["N"] for row in study.rows] == [4, 8]


def test_scene_pressure_of_an_elastic_study():
    # the facets' normal cannot be interpolated: p_h is the nodal (1/ε)[u_h·n − g0]_+^α; on this flat face its
    # largest value is the penetration's, (1/ε) max[w_h]_+^α, to round-off
    root = Path(__file__).resolve().parents[2]
    cfg = load(root / "configs/elasticity/square-alpha2.yaml", mesh__refinements=[4, 8])
    seen = []
    run(cfg, on_level=lambda level, u_h, scene: seen.append((level, scene.pressure.x.array.max())))
    assert len(seen) == 2
    for level, peak in seen:
        assert peak == pytest.approx(level.extra["penetration"] ** cfg.alpha / level.eps, rel=1e-12)
