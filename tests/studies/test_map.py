"""Rate maps: the grid's points validated before any solve, each point the very study it would be alone
(serial and on 2 ranks), map.csv the same on 1 and 2 ranks, a failing point recorded while the map goes
on, SIGTERM then --resume giving the map.csv of an uninterrupted run, chunks and report."""
import csv
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from mpi4py import MPI

from signorini_cli import config, studies
from signorini_cli.app import cli, maps
from signorini_cli.record import resume
from signorini_cli.studies import rate_map, refinement as refinement_study
from conftest import BASE, merge

SIGNORINI = str(Path(sys.executable).with_name("signorini"))
# the same code solves a point in a map and alone: the errors agree to round-off; 1e-12 relative is the
# bound the map promises (each point runs on one rank in both)
RTOL = 1e-12
SMALL = {"epsilon.theta": [0.1, 10], "alpha": [1.5, 3]}
# 4 theta x 3 alpha x 2 eps laws, N = 8..64: 24 points
FULL = {"epsilon.theta": [0.01, 0.1, 1, 10], "alpha": [1.5, 2, 3], "epsilon.law": ["theta_h", "theta_sqrt_h"]}
TIMES = ("time_s",)  # the columns that differ from run to run


def map_raw(folder, grid, refinements=(4, 8, 16), **changes):
    return merge(BASE, dict(changes, study="m", study_type="map", map={"grid": grid},
                            mesh={"refinements": list(refinements)},
                            output={"dir": str(folder), "plots": False}))


def write_map(folder, grid, refinements=(4, 8, 16), **changes):
    path = Path(folder) / "m.yaml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(map_raw(folder, grid, refinements, **changes), sort_keys=False))
    return str(path)


def map_rows(folder):
    with open(Path(folder) / "map.csv") as f:
        return [{k: v for k, v in row.items() if k not in TIMES} for row in csv.DictReader(f)]


@pytest.mark.fast
def test_grid_is_every_combination_in_order(tmp_path):
    cfg = config.loads(yaml.safe_dump(map_raw(tmp_path, SMALL), sort_keys=False))
    assert cfg.map.values == ({"epsilon.theta": 0.1, "alpha": 1.5}, {"epsilon.theta": 0.1, "alpha": 3},
                              {"epsilon.theta": 10, "alpha": 1.5}, {"epsilon.theta": 10, "alpha": 3})
    point = cfg.map.studies[2]
    assert (point.epsilon.theta, point.alpha, point.study_type) == (10, 1.5, "refinement")
    assert point.output_dir == tmp_path / "m" / "points" / "2"
    assert config.fingerprint(config.loads(point.text)) == config.fingerprint(point)  # it reads back


@pytest.mark.fast
def test_explicit_points_follow_the_grid(tmp_path):
    raw = map_raw(tmp_path, {"alpha": [2]})
    raw["map"]["points"] = [{"alpha": 3, "epsilon.law": "constant"}]
    cfg = config.loads(yaml.safe_dump(raw, sort_keys=False))
    assert cfg.map.varied == ("alpha", "epsilon.law")
    assert [s.epsilon.law for s in cfg.map.studies] == ["theta_h", "constant"]


@pytest.mark.fast
@pytest.mark.parametrize("grid, message", [
    pytest.param({"alpha": [2, 0.5]}, "map.grid.alpha: point 1 (alpha=0.5): alpha: must be >= 1, got 0.5",
                 id="value"),
    pytest.param({"epsilon.thta": [1]}, "map.grid.epsilon.thta: point 0 (epsilon.thta=1): epsilon.thta: unknown "
                 "key in epsilon (did you mean 'epsilon.theta'?)", id="key"),
    pytest.param({"output.dir": ["x"]}, "map.grid.output.dir: cannot vary", id="fixed"),
    pytest.param({"alpha": []}, "map.grid.alpha: must be a non-empty list", id="empty"),
])
def test_bad_grid_ends_before_any_solve(tmp_path, capsys, grid, message):
    path = write_map(tmp_path, grid)
    assert cli.main(["run", path]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"signorini: error: {path}: {message}")
    assert not (tmp_path / "m").exists()


def check_points_alone(cfg, comm):
    """Every point read back from its folder has the errors of the point solved alone, on one rank."""
    worst = 0.0
    for k, point in enumerate(cfg.map.studies):
        if k % comm.size != comm.rank:
            continue
        alone = studies.run_study(point, comm=MPI.COMM_SELF)
        recorded = resume.read_levels(point)
        assert [lv.n for lv in recorded] == [lv.n for lv in alone]
        for a, r in zip(alone, recorded):
            for norm in ("L2", "H1"):
                worst = max(worst, abs(r.errors[norm] - a.errors[norm]) / a.errors[norm])
    assert comm.allreduce(worst, op=MPI.MAX) <= RTOL


@pytest.mark.mpi
@pytest.mark.parametrize("grid, refinements", [
    pytest.param(SMALL, (4, 8, 16), id="4-points"),
    pytest.param(FULL, (8, 16, 32, 64), id="24-points", marks=pytest.mark.slow),
])
def test_points_are_their_single_studies(tmp_path_factory, grid, refinements):
    """Run on every rank of COMM_WORLD (groups of one rank), and again on COMM_SELF by rank 0: each
    point's errors are the point's alone, and map.csv is the same either way, timings aside."""
    comm = MPI.COMM_WORLD
    folder = Path(comm.bcast(str(tmp_path_factory.mktemp("map")) if comm.rank == 0 else None))
    cfg = config.loads(yaml.safe_dump(map_raw(folder / "world", grid, refinements), sort_keys=False))
    assert maps.exit_status(maps.run(cfg, quiet=True, comm=comm), comm) == 0
    check_points_alone(cfg, comm)
    if comm.rank == 0:
        alone = config.loads(yaml.safe_dump(map_raw(folder / "self", grid, refinements), sort_keys=False))
        assert maps.exit_status(maps.run(alone, quiet=True, comm=MPI.COMM_SELF), MPI.COMM_SELF) == 0
        assert map_rows(folder / "self" / "m") == map_rows(folder / "world" / "m")
        assert len(map_rows(folder / "world" / "m")) == len(cfg.map.studies)


@pytest.mark.mpi
@pytest.mark.parametrize("ranks_per_point", [1, 2])
def test_every_point_taken_once(ranks_per_point):
    """The groups take every point once, and a group's ranks agree on the points they take."""
    comm = MPI.COMM_WORLD
    group, count = rate_map.groups(comm, ranks_per_point)
    taken = list(rate_map.Dispenser([3, 5, 6, 8, 9, 11, 12], comm, group, count))
    assert group.allgather(taken) == [taken] * group.size
    leaders = comm.allgather(taken if group.rank == 0 else [])
    assert sorted(sum(leaders, [])) == [3, 5, 6, 8, 9, 11, 12]


@pytest.mark.mpi
def test_a_slow_group_takes_fewer_points():
    """Rank 0 spends 0.5 s on each of its points, rank 1 none: rank 1 takes the points rank 0 is busy with."""
    comm = MPI.COMM_WORLD
    group, count = rate_map.groups(comm, 1)
    taken = []
    for k in rate_map.Dispenser(range(6), comm, group, count):
        taken.append(k)
        if comm.rank == 0:
            time.sleep(0.5)
    assert comm.allgather(len(taken)) == [1, 5]


def test_failing_point_is_recorded_and_the_map_goes_on(tmp_path, capsys, monkeypatch):
    # an exception inside the first point's study (alpha = 2), as a bug in a level would raise
    solve_level = refinement_study.solve_level

    def fails_at_alpha_2(cfg, index, *args, **kwargs):
        if cfg.alpha == 2:
            raise RuntimeError("the level fails")
        return solve_level(cfg, index, *args, **kwargs)
    monkeypatch.setattr(refinement_study, "solve_level", fails_at_alpha_2)
    path = write_map(tmp_path, {"alpha": [2, 3]}, (4, 8))
    assert cli.main(["run", path]) == 1
    rows = map_rows(tmp_path / "m")
    assert rows[0]["status"].startswith("failed at level 0: RuntimeError") and rows[0]["converged"] == "false"
    assert rows[1]["status"] == "complete" and rows[1]["converged"] == "true"
    assert (tmp_path / "m" / "status.txt").read_text() == "complete\n"
    assert "point 0: failed at level 0" in capsys.readouterr().out


def test_chunks_then_report_give_the_whole_map(tmp_path, capsys):
    path = write_map(tmp_path, SMALL, (4, 8))
    assert cli.main(["run", path, "--points", "0-1", "--quiet"]) == 0
    assert [r["status"] for r in map_rows(tmp_path / "m")] == ["complete"] * 2 + ["not run"] * 2
    assert (tmp_path / "m" / "status.txt").read_text() == "partial (2 of 4 points done)\n"
    assert cli.main(["run", path, "--points", "2,3", "--quiet"]) == 0
    chunked = map_rows(tmp_path / "m")
    assert [r["status"] for r in chunked] == ["complete"] * 4
    (tmp_path / "m" / "map.csv").unlink()
    assert cli.main(["report", str(tmp_path / "m"), "--no-plots"]) == 0
    assert map_rows(tmp_path / "m") == chunked
    capsys.readouterr()
    assert cli.main(["report", str(tmp_path / "m"), "--columns", "pos_gc_scaled"]) == 2  # refused, not ignored
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("signorini: error:") and "--columns: applies to a study's" in err
    assert cli.main(["run", path, "--points", "2-9"]) == 2
    assert "--points: 2-9 is not within the map's points 0-3" in capsys.readouterr().err


def test_existing_map_needs_resume_or_force(tmp_path, capsys):
    path = write_map(tmp_path, {"alpha": [2]}, (4, 8))
    assert cli.main(["run", path, "--quiet"]) == 0
    assert cli.main(["run", path, "--quiet"]) == 2
    assert "already holds results; use --resume" in capsys.readouterr().err
    assert cli.main(["run", path, "--quiet", "--force"]) == 0


@pytest.mark.slow
def test_sigterm_then_resume_gives_the_uninterrupted_map(tmp_path):
    whole = write_map(tmp_path / "whole", SMALL, (8, 16, 32))
    assert subprocess.run([SIGNORINI, "run", whole, "--quiet"], timeout=600).returncode == 0
    path = write_map(tmp_path / "cut", SMALL, (8, 16, 32))
    run = subprocess.Popen([SIGNORINI, "run", path, "--quiet"], stderr=subprocess.PIPE, text=True)
    first = tmp_path / "cut" / "m" / "points" / "0" / "status.txt"
    deadline = time.monotonic() + 300
    while not (first.exists() and first.read_text() == "complete\n") and time.monotonic() < deadline:
        time.sleep(0.05)
    run.send_signal(signal.SIGTERM)
    assert run.wait(timeout=60) == 128 + signal.SIGTERM
    assert "continue with --resume" in run.stderr.read()
    assert (tmp_path / "cut" / "m" / "status.txt").read_text().startswith("interrupted (")
    assert subprocess.run([SIGNORINI, "run", path, "--quiet", "--resume"], timeout=600).returncode == 0
    assert map_rows(tmp_path / "cut" / "m") == map_rows(tmp_path / "whole" / "m")


@pytest.mark.slow
@pytest.mark.skipif(os.environ.get("OMPI_COMM_WORLD_SIZE") is not None, reason="starts mpirun itself")
def test_jobs_run_under_mpirun(tmp_path):
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    serial = write_map(tmp_path / "serial", SMALL, (4, 8))
    jobs = write_map(tmp_path / "jobs", SMALL, (4, 8))
    assert subprocess.run([SIGNORINI, "run", serial, "--quiet"], env=env, timeout=600).returncode == 0
    done = subprocess.run([SIGNORINI, "run", jobs, "--quiet", "--set", "map.jobs=2"], env=env, timeout=600)
    assert done.returncode == 0
    assert map_rows(tmp_path / "jobs" / "m") == map_rows(tmp_path / "serial" / "m")


@pytest.mark.fast
def test_map_row_shows_the_rate_run_and_compare_show(make_config):
    # alpha = 3: the proven L2 rate carries |ln h|; the map's rate is still the plain slope, the verdict's,
    # and the log-corrected fit is its own column
    from signorini_cli.analysis import rates, verdict
    from signorini_cli.solve.solver import Outcome
    cfg = make_config(alpha=3.0)
    h = [math.sqrt(2) / n for n in (8, 16, 32, 64)]
    e = [x**2 * -math.log(x) for x in h]
    outcome = Outcome(True, "CONVERGED_FNORM_ABS", 5, 5, (1.0,))
    levels = [studies.Level(k, n, x, 100, x, outcome, {"L2": y}, 1.0)
              for k, (n, x, y) in enumerate(zip((8, 16, 32, 64), h, e))]
    row = rate_map.row(cfg, {}, levels, "complete", ())
    (l2,) = verdict.summarize(cfg, levels).norms
    assert row["rate_L2"] == l2.observed == rates.slope(h, e)
    assert row["rate_L2_log"] == l2.log_corrected == rates.fitted(h, e, [True] * 4, log_factor=True)
