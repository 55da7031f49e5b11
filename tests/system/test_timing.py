"""Per-phase timings, work-precision data and the speed work."""
import csv
import time

import pytest
from mpi4py import MPI

from signorini_cli import studies
from signorini_cli.analysis import rates
from signorini_cli.app import cli
from signorini_cli.record import results
from signorini_cli.system import timing
from conftest import merge

CUBE = {"dimension": 3, "mesh": {"kind": "unit_cube"}, "problem": {"exact": "sin(2*pi*x)*sin(pi*y)*(1-z)**2"}}
# the fast paths of the speed work (split assembly, lagged AMG set-up, CG + AMG, the Kuhn-grid transfer of
# nested iteration) against the plain path: Newton from zero with MUMPS on every level
SCENES = {"2d-direct": ({"solver": {"linear": "direct"}}, [8, 16, 32, 64]),
          "2d-iterative": ({"solver": {"linear": "iterative"}}, [8, 16, 32, 64]), "3d": (CUBE, [4, 8, 16])}
PLAIN = {"solver": {"linear": "direct", "strategy": "plain"}}


def test_phases_accumulate_and_take_the_slowest_rank():
    phases = timing.Phases()
    for _ in range(2):
        with phases("mesh"):
            time.sleep(0.01)
    phases.deduct("mesh", 0.005)
    columns = phases.columns(MPI.COMM_SELF)
    assert list(columns) == [f"t_{name}" for name in timing.PHASES]
    # two sleeps of at least 10 ms each, less 5 ms (no upper bound: a loaded machine sleeps longer)
    assert columns["t_mesh"] >= 0.015 and columns["t_newton"] == 0.0


@pytest.mark.parametrize("scene", list(SCENES))
def test_errors_of_the_fast_paths_equal_the_plain_path(scene, make_config):
    changes, refinements = SCENES[scene]
    runs = [studies.run_study(make_config(**merge(merge(changes, extra), {"mesh": {"refinements": refinements}})),
                            comm=MPI.COMM_SELF) for extra in ({}, PLAIN)]
    fast, plain = ([lv.errors[norm] for norm in ("L2", "H1") for lv in levels] for levels in runs)
    # both solve one discrete problem, each polished to a predicted algebraic error <= 1e-13 ||u_h||
    # (solver.polish), so errors down to 1e-3 ||u_h|| agree to ~1e-10: observed 1.5e-10 (2-D), 5e-16 (3-D)
    assert fast == pytest.approx(plain, rel=1e-9)


def test_phase_columns_split_the_level_time(tmp_path, make_config):
    cfg = make_config(mesh={"refinements": [8, 16, 32]}, solver={"linear_floor": True})
    levels = studies.run_study(cfg, on_level=lambda done: results.write(studies.study_of(cfg, done)),
                               comm=MPI.COMM_SELF)
    rows = studies.level.rate_table(levels)
    for row in rows:
        # the level's own phases split time_s; t_output (the record written after time_s was taken) apart
        parts = [row[f"t_{name}"] for name in timing.PHASES if name not in ("linear", "pc_setup", "newton", "output")]
        assert all(value >= 0 for value in parts) and row["t_output"] >= 0
        assert sum(parts) <= row["time_s"] + 1e-9
        assert row["t_pc_setup"] <= row["t_linear"] <= row["t_newton"] <= row["time_s"]
        assert row["floor_ratio"] == pytest.approx(row["t_newton"] / row["t_linear_floor"])
        assert row["peak_memory_mb"] > 50  # the interpreter with dolfinx and PETSc alone is ~100 MiB
    assert [row["cumulative_time_s"] for row in rows] == pytest.approx(
        [sum(r["time_s"] for r in rows[:k + 1]) for k in range(len(rows))])


def test_work_precision_csv_has_every_norm_and_level(tmp_path, make_config):
    path = tmp_path / "c.yaml"
    cfg = make_config(mesh={"refinements": [4, 8]}, output={"plots": False})
    path.write_text(cfg.text)
    assert cli.main(["run", str(path), "--quiet"]) == cli.EXIT_OK
    with open(cfg.output_dir / "rates.csv") as f:
        table = list(csv.DictReader(f))
    with open(cfg.output_dir / "work_precision.csv") as f:
        work = list(csv.DictReader(f))
    assert list(work[0]) == list(studies.level.WORK_PRECISION_COLUMNS)
    norms = rates.error_columns(table)
    assert {"L2", "H1", "L2_gc", "energy_err"} <= set(norms)
    assert len(work) == len(norms) * len(table)
    for row in work:
        level = table[int(row["level"])]
        assert row["error"] == level[row["norm"]] and row["cumulative_time_s"] == level["cumulative_time_s"]
    # the last level's record is written again once it has its own output time
    assert all(float(row["t_output"]) > 0 for row in table)


def test_no_floor_columns_unless_asked(make_config):
    (level,) = studies.run_study(make_config(mesh={"refinements": [4]}), comm=MPI.COMM_SELF)
    assert "t_linear_floor" not in level.timings and "floor_ratio" not in level.timings
