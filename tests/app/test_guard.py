"""Interruptions and faults: SIGINT/SIGTERM leave valid results and a status, --resume then gives the
table of an uninterrupted run; a failure on one rank of two ends both."""
import csv
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import h5py
import pytest
import yaml

from signorini_cli import studies
from signorini_cli.studies import refinement as refinement_study
from signorini_cli.app import cli, guard
from signorini_cli.record import results
from signorini_cli.solve import solver
import failing_run
from conftest import BASE, merge

LEVELS = [4, 8, 12, 16]
LONG_LEVELS = [4, 8, 16, 32, 48, 64, 80]  # ~1 s once started, most of it in the last three levels
SIGNORINI = str(Path(sys.executable).with_name("signorini"))
FAILING_RUN = failing_run.__file__
MPI_ENV = dict(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")


def write_config(folder, refinements=LEVELS, **changes):
    path = folder / "c.yaml"
    path.write_text(yaml.safe_dump(merge(BASE, dict(changes, mesh={"refinements": refinements},
                                                    output={"plots": False}))))  # figures cost ~2 s a run
    return str(path)


def table(folder):
    """rates.csv without the timing columns (wall times differ between runs), as strings."""
    with open(Path(folder) / "t" / "rates.csv") as f:
        return [{k: v for k, v in row.items() if not results.is_timing(k)} for row in csv.DictReader(f)]


def status(folder):
    return (Path(folder) / "t" / "status.txt").read_text().strip()


def uninterrupted(folder, refinements):
    """(table, the levels' total time_s) of an uninterrupted run."""
    assert cli.main(["run", write_config(folder, refinements), "--output", str(folder / "out"), "--quiet"]) == 0
    assert status(folder / "out") == "complete"
    with open(folder / "out" / "t" / "rates.csv") as f:
        return table(folder / "out"), sum(float(row["time_s"]) for row in csv.DictReader(f))


@pytest.fixture(scope="module")
def whole(tmp_path_factory):
    """The table of an uninterrupted run of LEVELS, for comparison."""
    return uninterrupted(tmp_path_factory.mktemp("whole"), LEVELS)[0]


def signal_at_level(monkeypatch, level, signum):
    """Deliver `signum` to this process as `level` starts solving (after the earlier ones are written)."""
    solve = refinement_study.solve_level

    def solve_or_signal(cfg, index, n, *args):
        if index == level:
            os.kill(os.getpid(), signum)
        return solve(cfg, index, n, *args)
    monkeypatch.setattr(refinement_study, "solve_level", solve_or_signal)


def check_kept(out, k):
    """The finished levels 0..k-1 are in rates.csv and study.h5, with the status interrupted at level k."""
    assert status(out) == f"interrupted at level {k}"
    assert [row["level"] for row in table(out)] == [str(i) for i in range(k)]
    with h5py.File(Path(out) / "t" / "study.h5") as h5:
        assert h5.attrs["levels_done"] == k and h5.attrs["status"] == f"interrupted at level {k}"
    assert not list((Path(out) / "t").glob(".*.tmp*"))


@pytest.mark.parametrize("signum, level", [
    pytest.param(signal.SIGTERM, 2, id="sigterm-level2"),
    pytest.param(signal.SIGINT, 0, id="sigint-level0"),
    pytest.param(signal.SIGHUP, 1, id="sighup-level1"),  # the terminal went away: a termination request
])
def test_signal_keeps_levels_and_resume_completes(whole, tmp_path, monkeypatch, capsys, signum, level):
    config, out = write_config(tmp_path), str(tmp_path / "out")
    previous = signal.getsignal(signum)
    signal_at_level(monkeypatch, level, signum)
    assert cli.main(["run", config, "--output", out, "--quiet"]) == 128 + signum
    assert signal.getsignal(signum) is previous  # main gives the handlers back
    err = capsys.readouterr().err
    assert err == (f"signorini: interrupted by {signal.Signals(signum).name} at level {level}: the {level} "
                   f"finished level(s) are in {out}/t; continue with --resume\n")
    check_kept(out, level)
    monkeypatch.undo()
    assert cli.main(["run", config, "--output", out]) == cli.EXIT_BAD_INPUT  # neither --resume nor --force
    assert "use --resume to continue them or --force to overwrite" in capsys.readouterr().err
    assert cli.main(["run", config, "--output", out, "--resume"]) == cli.EXIT_OK
    assert table(out) == whole and status(out) == "complete"


def test_resume_data_only_scene_keeps_successive_differences(tmp_path, monkeypatch):
    """A data-only scene measures diff_L2/diff_H1 against the previous level's u_h: the first resumed
    level gets them too (the last finished level is solved again for its u_h)."""
    data_only = {"problem": {"exact": None, "f": "-10"}}
    config, out = write_config(tmp_path, [4, 8, 16], **data_only), str(tmp_path / "out")
    assert cli.main(["run", config, "--output", str(tmp_path / "whole"), "--quiet"]) == cli.EXIT_OK
    whole = table(tmp_path / "whole")
    signal_at_level(monkeypatch, 2, signal.SIGTERM)
    assert cli.main(["run", config, "--output", out, "--quiet"]) == 128 + signal.SIGTERM
    monkeypatch.undo()
    assert cli.main(["run", config, "--output", out, "--resume", "--quiet"]) == cli.EXIT_OK
    assert table(out)[2]["diff_L2"] != "" and table(out) == whole


def test_signal_inside_newton_then_resume(whole, tmp_path, monkeypatch):
    """SIGTERM while PETSc runs Newton on level 1 (from inside the residual callback)."""
    config, out = write_config(tmp_path), str(tmp_path / "out")
    residual, calls = solver.NewtonSolver._residual, []

    def residual_or_signal(self, snes, x, F):
        calls.append(self.u.function_space.dofmap.index_map.size_global)
        if calls.count(9**2) == 3:  # level 1: N=8, 81 vertices; its third residual
            os.kill(os.getpid(), signal.SIGTERM)
        residual(self, snes, x, F)
    monkeypatch.setattr(solver.NewtonSolver, "_residual", residual_or_signal)
    assert cli.main(["run", config, "--output", out]) == 128 + signal.SIGTERM
    check_kept(out, 1)
    monkeypatch.undo()
    assert cli.main(["run", config, "--output", out, "--resume"]) == cli.EXIT_OK
    assert table(out) == whole


def test_signal_while_writing_waits_for_the_level(tmp_path, monkeypatch):
    """A signal during the writing of level 1's results is held until they are written whole."""
    from signorini_cli.record import results
    config, out = write_config(tmp_path), str(tmp_path / "out")
    write_files = results.write_files

    def write_with_signal(study, *args):
        if study.solves == 2:
            os.kill(os.getpid(), signal.SIGTERM)
        write_files(study, *args)
    monkeypatch.setattr(results, "write_files", write_with_signal)
    assert cli.main(["run", config, "--output", out]) == 128 + signal.SIGTERM
    check_kept(out, 2)


@pytest.mark.parametrize("level", [0, 3])
def test_crash_inside_level_records_failure(whole, tmp_path, monkeypatch, level):
    """A bug keeps its traceback (the exception propagates) but the status says where it happened."""
    config, out = write_config(tmp_path), str(tmp_path / "out")
    solve_level = refinement_study.solve_level
    monkeypatch.setattr(refinement_study, "solve_level", failing_run.failing(solve_level, 0, level))
    with pytest.raises(RuntimeError, match=f"rank 0 fails at the start of level {level}"):
        cli.main(["run", config, "--output", out])
    assert status(out) == f"failed at level {level}: RuntimeError: rank 0 fails at the start of level {level}"
    assert len(table(out)) == level
    monkeypatch.setattr(refinement_study, "solve_level", solve_level)
    assert cli.main(["run", config, "--output", out, "--resume"]) == cli.EXIT_OK
    assert table(out) == whole


def test_stopped_study_status_and_resume_is_a_no_op(tmp_path, capsys):
    config, out = write_config(tmp_path, solver={"max_it": 1, "on_failure": "stop"}), str(tmp_path / "out")
    assert cli.main(["run", config, "--output", out]) == cli.EXIT_NOT_CONVERGED
    assert status(out) == "failed at level 0: DIVERGED_MAX_IT" and len(table(out)) == 1
    before = table(out)
    assert cli.main(["run", config, "--output", out, "--resume"]) == cli.EXIT_NOT_CONVERGED
    assert table(out) == before and status(out) == "failed at level 0: DIVERGED_MAX_IT"


def fake_level(index, converged=True, reason="CONVERGED_FNORM_RELATIVE"):
    return SimpleNamespace(index=index, outcome=SimpleNamespace(converged=converged, reason=reason))


@pytest.mark.parametrize("levels, on_failure, expected", [
    pytest.param([], "continue", "running (0 of 3 levels done)", id="start"),
    pytest.param([fake_level(0)], "continue", "running (1 of 3 levels done)", id="running"),
    pytest.param([fake_level(i) for i in range(3)], "continue", "complete", id="complete"),
    pytest.param([fake_level(0), fake_level(1, False, "DIVERGED_FNORM_NAN")], "stop",
                 "failed at level 1: DIVERGED_FNORM_NAN", id="stopped"),
    pytest.param([fake_level(0), fake_level(1, False), fake_level(2)], "continue",
                 "complete: 2 of 3 levels converged", id="complete-with-failed-level"),
])
def test_status(make_config, levels, on_failure, expected):
    cfg = make_config(mesh={"refinements": [4, 8, 16]}, solver={"on_failure": on_failure})
    assert guard.status(cfg, levels) == expected


def test_status_before_the_figures_is_not_complete(make_config):
    """Every level done, tables and figures not yet written (final=False): still running."""
    cfg = make_config(mesh={"refinements": [4, 8, 16]})
    assert guard.status(cfg, [fake_level(i) for i in range(3)], final=False) == "running (3 of 3 levels done)"


def test_sigterm_at_random_point_then_resume(tmp_path):
    """`signorini run` in its own process, SIGTERM at a random moment of the study, then --resume."""
    (tmp_path / "whole").mkdir()
    whole, seconds = uninterrupted(tmp_path / "whole", LONG_LEVELS)
    config, out = write_config(tmp_path, LONG_LEVELS), tmp_path / "out"
    seed = random.randrange(2**32)
    delay = random.Random(seed).uniform(0.0, seconds)  # within the levels, as timed in this process
    proc = subprocess.Popen([SIGNORINI, "run", config, "--output", str(out), "--quiet"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    started = time.monotonic()
    while not (out / "t" / "status.txt").exists() and proc.poll() is None and time.monotonic() - started < 120:
        time.sleep(0.02)  # status.txt appears once the handlers are in place and the study begins
    time.sleep(delay)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    state, k = status(out), len(table(out))
    note = f"seed {seed}, delay {delay:.3f} s, exit {proc.returncode}, status {state!r}, stderr {err!r}"
    assert "Traceback" not in err, note
    if proc.returncode == 128 + signal.SIGTERM:
        assert state in (f"interrupted at level {k}", "complete"), note
        assert err.startswith("signorini: interrupted by SIGTERM") and err.count("\n") == 1, note
    else:  # the study had finished before the signal came
        assert proc.returncode == cli.EXIT_OK and state == "complete", note
    assert cli.main(["run", config, "--output", str(out), "--resume"]) == cli.EXIT_OK
    assert table(out) == whole, note


@pytest.mark.skipif(shutil.which("mpirun") is None, reason="needs mpirun")
def test_one_rank_fails_both_end(tmp_path):
    """Rank 1 alone raises as level 1 starts, while rank 0 goes on into level 1's collectives: the MPI
    abort ends both (subprocess timeout: 60 s; it takes ~4 s here) with the traceback printed once."""
    config, out = write_config(tmp_path), tmp_path / "out"
    env = dict(os.environ, **MPI_ENV)
    done = subprocess.run(["mpirun", "-q", "-n", "2", sys.executable, FAILING_RUN, "1", "1", "run", config,
                           "--output", str(out)], capture_output=True, text=True, env=env, timeout=60)
    assert done.returncode == guard.CRASH_STATUS  # MPI_Abort's code, through mpirun
    assert done.stderr.count("Traceback") == 1, done.stderr
    assert "signorini: rank 1 failed: RuntimeError: rank 1 fails at the start of level 1" in done.stderr
    assert status(out) == "failed at level 1: RuntimeError: rank 1 fails at the start of level 1"
    assert [row["level"] for row in table(out)] == ["0"]


def test_crash_exits_3_with_one_traceback(tmp_path):
    """The console script keeps a bug's traceback and exits 3, apart from 1 (not converged) and 2 (bad input)."""
    config, out = write_config(tmp_path), tmp_path / "out"
    done = subprocess.run([sys.executable, FAILING_RUN, "0", "1", "run", config, "--output", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == guard.CRASH_STATUS and done.stderr.count("Traceback") == 1, done.stderr
    assert status(out) == "failed at level 1: RuntimeError: rank 0 fails at the start of level 1"
