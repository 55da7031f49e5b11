"""Faults around rate maps: every check of a single study before any point solves (exit 2, one line naming the
point, nothing written); --points that name no point; --resume with levels added; who may write one map
folder at once (chunks together, a whole run alone, report and runs one finisher at a time), each race tried
again and again; SIGTERM to the ranks of a 2-rank map; report --output; --force with a smaller grid; the API
on maps and on a folder another run writes."""
import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from mpi4py import MPI

from signorini_cli import load, run as api_run
from signorini_cli.app import cli, guard, maps
from signorini_cli.config import ConfigError
from conftest import BASE, merge

SIGNORINI = str(Path(sys.executable).with_name("signorini"))
TOGETHER = str(Path(__file__).with_name("together.py"))
# the same levels solved in one run or resumed with levels appended: the errors agree to round-off (each
# point on one rank both times; nested iteration solves the finished chain again); 1e-12 relative is the
# bound --resume promises
RTOL = 1e-12
TRIES = 10  # each race below failed in at least 3 of 12 tries before the map folder's locks
STAGED_TRIES = 2  # runs started one after the other, at a set point: no race to repeat
MPI_ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")


def write_map(folder, grid, refinements=(2, 4), name="m.yaml", **changes):
    path = Path(folder) / name
    path.parent.mkdir(parents=True, exist_ok=True)
    block = {"grid": grid, **changes.pop("map", {})}
    raw = merge(BASE, dict(changes, study="m", study_type="map", map=block,
                           mesh={"refinements": list(refinements)}, output={"dir": str(folder), "plots": False}))
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return str(path)


def tree(folder):
    return sorted(str(p.relative_to(folder)) for p in Path(folder).rglob("*"))


def rows(folder):
    with open(Path(folder) / "map.csv") as f:
        return list(csv.DictReader(f))


def status(folder):
    return (Path(folder) / "status.txt").read_text().strip()


def one_line(capsys):
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("signorini: error: "), err
    return err


# --- a map point gets every check of a single study, before any point is solved -------------------------

@pytest.mark.parametrize("changes, grid, message", [
    pytest.param({}, {"mesh.refinements": [[2, 4], [4, 20000]]},
                 "map.grid.mesh.refinements: point 1 (mesh.refinements=[4, 20000]): mesh.refinements: the finest "
                 "level (N=20000", id="memory"),
    pytest.param({"solver": {"petsc_options": {"pc_type": "ilu"}}}, {"alpha": [2, 3]},
                 "solver.petsc_options: point 0 (alpha=2): PETSc rejects these options", id="petsc-option"),
    pytest.param({"contact_quadrature": "exact"}, {"alpha": [2, 1023]},
                 "map.grid.alpha: point 1 (alpha=1023): alpha: 1023 is above 1022", id="alpha-exact-rule"),
    pytest.param({}, {"problem.exact": ["x*(1-y)", "sin(sqrt(x*x+y*y))/sqrt(x*x+y*y)"]},
                 "map.grid.problem.exact: point 1 (problem.exact=sin(sqrt(x*x+y*y))/sqrt(x*x+y*y)): problem.exact: "
                 "sin(sqrt(x*x+y*y))/sqrt(x*x+y*y) is nan at (0, 0)", id="data-not-finite"),
    pytest.param({"map": {"ranks_per_point": 2}}, {"alpha": [2]},
                 "map.ranks_per_point: must divide the 1 MPI ranks, got 2", id="ranks-per-point"),
])
def test_bad_point_refused_before_any_solve_nothing_written(tmp_path, capsys, changes, grid, message):
    """What a single study refuses before its first level, a map refuses for any of its points before its
    first point (it used to solve points and fail each, or build an 11 GiB mesh): exit 2, one line."""
    path = write_map(tmp_path / "cfg", grid, **changes)
    assert cli.main(["run", path, "--output", str(tmp_path / "out")]) == cli.EXIT_BAD_INPUT
    assert one_line(capsys).startswith(f"signorini: error: {path}: {message}")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("points", ["", "2-", "-", ",", "1,"])
def test_points_naming_no_point_refused(tmp_path, capsys, points):
    """`--points ""` ran the whole map and `--points 2-` point 2 alone."""
    path = write_map(tmp_path / "cfg", {"alpha": [2, 3, 4]})
    assert cli.main(["run", path, "--output", str(tmp_path / "out"), "--points", points]) == cli.EXIT_BAD_INPUT
    assert one_line(capsys) == (f"signorini: error: {path}: --points: expected ranges such as 0-49,60, "
                                f"got {points!r}\n")
    assert not (tmp_path / "out").exists()


def test_jobs_as_root_give_mpirun_its_root_variables(monkeypatch):
    """map.jobs > 1 as root without Open MPI's root variables: mpirun refused with its 13-line banner."""
    started = {}
    monkeypatch.setattr(os, "geteuid", lambda: 0)
    monkeypatch.setattr(os, "execve", lambda path, argv, env: started.update(argv=argv, env=env))
    for name in maps.ROOT_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    maps.relaunch(1)
    assert started["argv"][1:4] == ["-q", "-n", "1"]
    assert all(started["env"][name] == "1" for name in maps.ROOT_VARIABLES)


def test_more_jobs_than_cpus_refused(tmp_path, capsys):
    """map.jobs above the CPUs this process may use: one line (mpirun refused it with a 10-line banner)."""
    cpus = len(os.sched_getaffinity(0))
    path = write_map(tmp_path / "cfg", {"alpha": [2]}, map={"jobs": cpus + 1})
    assert cli.main(["run", path, "--output", str(tmp_path / "out")]) == cli.EXIT_BAD_INPUT
    assert one_line(capsys) == (f"signorini: error: {path}: map.jobs: {cpus + 1} workers, but this process may "
                                f"use {cpus} CPUs; set map.jobs <= {cpus}, or run the map under mpirun -n N "
                                "yourself\n")
    assert not (tmp_path / "out").exists()


# --- --resume of a complete map with levels added ---------------------------------------------------------

def test_resume_with_levels_added_extends_every_point(tmp_path):
    """A complete 3-level map resumed with a 4th level: every point goes on to 4 levels (it used to say
    complete with 3), with the errors of a 4-level map run at once."""
    grid = {"alpha": [1.5, 3]}
    path = write_map(tmp_path / "cut", grid, refinements=(2, 4, 8))
    assert cli.main(["run", path, "--quiet"]) == cli.EXIT_OK
    assert cli.main(["run", path, "--quiet", "--resume", "--set", "mesh.refinements=[2,4,8,16]"]) == cli.EXIT_OK
    whole = write_map(tmp_path / "whole", grid, refinements=(2, 4, 8, 16))
    assert cli.main(["run", whole, "--quiet"]) == cli.EXIT_OK
    assert status(tmp_path / "cut" / "m") == "complete"
    for k in range(2):
        with open(tmp_path / "cut" / "m" / "points" / str(k) / "rates.csv") as f:
            extended = list(csv.DictReader(f))
        with open(tmp_path / "whole" / "m" / "points" / str(k) / "rates.csv") as f:
            alone = list(csv.DictReader(f))
        assert [row["N"] for row in extended] == ["2", "4", "8", "16"]
        for a, b in zip(extended, alone):
            assert abs(float(a["L2"]) - float(b["L2"])) <= RTOL * float(b["L2"])
    for a, b in zip(rows(tmp_path / "cut" / "m"), rows(tmp_path / "whole" / "m")):
        assert abs(float(a["rate_L2"]) - float(b["rate_L2"])) <= 1e-9  # a fit of errors equal to 1e-12


# --- who writes a map folder at once ----------------------------------------------------------------------

def together(tmp_path, first, second, timeout=600):
    """Run together.py twice at once (arguments `first`, `second`); their stdout's lines and stderr."""
    procs = [subprocess.Popen([sys.executable, TOGETHER, *args], cwd=tmp_path, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for args in (first, second)]
    outs = [proc.communicate(timeout=timeout) for proc in procs]
    assert [proc.returncode for proc in procs] == [0, 0], outs
    return [out.splitlines() for out, _ in outs], [err for _, err in outs]


def test_chunks_started_together_write_the_whole_map(tmp_path):
    """`--points 0-1` and `--points 2-3` started within a millisecond of each other, TRIES times: every
    try exits 0 on both and leaves the map complete (they used to fail with 'Directory not empty', 'File
    exists' or 'points is not a folder' as both made and removed the points' folder)."""
    path = write_map(tmp_path, {"alpha": [1.5, 2, 2.5, 3]}, refinements=(2, 3))
    (tmp_path / "sync").mkdir()
    outs, errs = together(tmp_path, [str(TRIES), "sync/a{k}", "sync/b{k}", "--", "run", path, "--quiet",
                                     "--output", "out/{k}", "--points", "0-1"],
                          [str(TRIES), "sync/b{k}", "sync/a{k}", "--", "run", path, "--quiet",
                           "--output", "out/{k}", "--points", "2-3"])
    assert outs == [[f"try {k}: 0" for k in range(TRIES)]] * 2 and errs == ["", ""], errs
    assert [status(tmp_path / "out" / str(k) / "m") for k in range(TRIES)] == ["complete"] * TRIES


def test_report_while_the_last_point_runs_leaves_the_run_complete(tmp_path):
    """`signorini report` started as the last point starts, TRIES times: the run ends `complete` (the
    report's `partial` used to be written after the run's `complete`); report and run each exit 0."""
    path = write_map(tmp_path, {"alpha": [1.5, 2, 2.5]})
    (tmp_path / "sync").mkdir()
    outs, errs = together(tmp_path, [str(TRIES), "-", "sync/report{k}", "--", "run", path, "--quiet",
                                     "--output", "out/{k}"],
                          [str(TRIES), "sync/report{k}", "out/{k}/m/points/2/status.txt=running", "--",
                           "report", "out/{k}/m"])
    assert outs[0] == [f"try {k}: 0" for k in range(TRIES)] and errs[0] == "", errs
    assert [line for line in outs[1] if line.startswith("try ")] == [f"try {k}: 0" for k in range(TRIES)], errs
    assert [status(tmp_path / "out" / str(k) / "m") for k in range(TRIES)] == ["complete"] * TRIES


@pytest.mark.parametrize("first", ["whole", "chunk"])
def test_whole_run_and_chunk_one_refused(tmp_path, first):
    """A whole run and a chunk of one map, the second started as the first's point 0 starts (the first then
    holds the folder for about 2 s more: points of 0.9 s each): the first writes, the second is refused
    before writing (a chunk used to ignore the whole run's lock and both wrote the same points). Both started
    within a millisecond is no test of this: the one that reaches the lock first may finish before the
    other reaches it, and then both rightly write, one after the other."""
    path = write_map(tmp_path, {"alpha": [1.5, 2, 2.5, 3]}, refinements=(16, 64, 256))
    (tmp_path / "sync").mkdir()
    whole = ["--", "run", path, "--quiet", "--output", "out/{k}"]
    chunk = whole + ["--points", "0-1"]
    holder, refused = (whole, chunk) if first == "whole" else (chunk, whole)
    outs, errs = together(tmp_path, [str(STAGED_TRIES), "-", "-", *holder],
                          [str(STAGED_TRIES), "-", "out/{k}/m/points/0/status.txt=running", *refused])
    assert outs == [[f"try {k}: {code}" for k in range(STAGED_TRIES)] for code in (0, 2)], (outs, errs)
    busy = ("is being written by another signorini run; a whole run of a map writes its folder alone, while "
            "chunks (--points) of one map may run together")
    assert errs[0] == "" and [busy in line for line in errs[1].splitlines()] == [True] * STAGED_TRIES, errs
    wrote = "complete" if first == "whole" else "partial (2 of 4 points done)"
    assert [status(tmp_path / "out" / str(k) / "m") for k in range(STAGED_TRIES)] == [wrote] * STAGED_TRIES


def test_chunk_leaves_a_point_another_chunk_writes(tmp_path, capsys):
    """Chunks whose points overlap: a point locked by another chunk is left to it (not written twice)."""
    path = write_map(tmp_path, {"alpha": [1.5, 2, 2.5]})
    out = tmp_path / "out"
    with guard.FolderLock(out / "m" / "points" / "1", MPI.COMM_WORLD):  # what the other chunk holds
        assert cli.main(["run", path, "--output", str(out), "--points", "0-2", "--quiet"]) == cli.EXIT_OK
    assert [row["status"] for row in rows(out / "m")] == ["complete", "not run", "complete"]
    assert status(out / "m") == "partial (2 of 3 points done)"
    assert cli.main(["run", path, "--output", str(out), "--points", "0-2", "--quiet", "--resume"]) == cli.EXIT_OK
    assert status(out / "m") == "complete"


# --- signals ----------------------------------------------------------------------------------------------

@pytest.mark.skipif(os.environ.get("OMPI_COMM_WORLD_SIZE") is not None, reason="starts mpirun itself")
def test_sigterm_to_both_ranks_of_a_map_one_line_no_traceback(tmp_path):
    """SIGTERM to both ranks of a 2-rank map (as a batch system signals a job's processes): exit 143, the
    one line, no traceback (rank 1 met mpirun's second SIGTERM while it waited to report the first)."""
    path = write_map(tmp_path, {"alpha": [1.5, 2, 2.5, 3]}, refinements=(8, 16, 32, 64, 128))
    proc = subprocess.Popen(["mpirun", "-n", "2", SIGNORINI, "run", path, "--quiet"], env=MPI_ENV,
                            stderr=subprocess.PIPE, text=True)
    first = tmp_path / "m" / "points" / "0" / "status.txt"
    deadline = time.monotonic() + 300
    while not (first.exists() and first.read_text() == "complete\n") and time.monotonic() < deadline:
        time.sleep(0.02)
    ranks = subprocess.run(["pgrep", "-P", str(proc.pid)], capture_output=True, text=True).stdout.split()
    assert len(ranks) == 2
    for pid in ranks:
        os.kill(int(pid), signal.SIGTERM)
    assert proc.wait(timeout=120) == 128 + signal.SIGTERM
    err = proc.stderr.read()
    assert "Traceback" not in err and err.count("signorini: interrupted by SIGTERM at map point") == 1, err
    assert status(tmp_path / "m").startswith("interrupted (")


# --- files: report --output, --force with a smaller grid, an empty compiler cache -------------------------

def test_report_output_writes_there_and_leaves_the_map(tmp_path):
    path = write_map(tmp_path, {"alpha": [2, 3]})
    assert cli.main(["run", path, "--quiet"]) == cli.EXIT_OK
    before = {name: (tmp_path / "m" / name).read_bytes() for name in tree(tmp_path / "m")
              if (tmp_path / "m" / name).is_file()}
    assert cli.main(["report", str(tmp_path / "m"), "--output", str(tmp_path / "rep"), "--no-plots"]) == 0
    assert tree(tmp_path / "rep") == ["map.csv", "map.md", "map.tex"]
    assert rows(tmp_path / "rep") == rows(tmp_path / "m")
    assert {name: (tmp_path / "m" / name).read_bytes() for name in before} == before


def test_report_of_a_map_refuses_a_study_tables_options(tmp_path, capsys):
    path = write_map(tmp_path, {"alpha": [2]})
    assert cli.main(["run", path, "--quiet"]) == cli.EXIT_OK
    assert cli.main(["report", str(tmp_path / "m"), "--digits", "2"]) == cli.EXIT_BAD_INPUT
    assert one_line(capsys) == (f"signorini: error: {tmp_path / 'm'}: --digits: applies to a study's tables and "
                                "figures; a map's report has no such option\n")


def test_force_with_a_smaller_grid_removes_the_old_figures_and_points(tmp_path):
    path = write_map(tmp_path, {"alpha": [2, 3], "epsilon.theta": [1, 10]})
    assert cli.main(["run", path, "--quiet", "--set", "output.plots=true"]) == cli.EXIT_OK
    assert any(name.startswith("heat_") for name in tree(tmp_path / "m"))
    (tmp_path / "m" / "points" / "3" / "notes.txt").write_text("mine")  # not a file a run writes: it stays
    assert cli.main(["run", path, "--quiet", "--force", "--set", "map.grid={alpha: [2, 3]}"]) == cli.EXIT_OK
    assert not any(name.startswith(("heat_", "rate_")) for name in tree(tmp_path / "m"))
    assert sorted(os.listdir(tmp_path / "m" / "points")) == ["0", "1", "3"]
    assert os.listdir(tmp_path / "m" / "points" / "3") == ["notes.txt"]
    assert len(rows(tmp_path / "m")) == 2


def test_empty_compiler_cache_quiet_prints_nothing(tmp_path):
    """With FFCx's cache empty, the forms compile: gcc's unused-variable warnings on FFCx's code (12 lines
    for output.fields of a polynomial solution) stay off stderr."""
    raw = merge(BASE, {"mesh": {"refinements": [2]}, "problem": {"exact": "x*(1-y)"},
                       "output": {"dir": str(tmp_path / "out"), "plots": False, "fields": True}})
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(raw))
    env = dict(os.environ, XDG_CACHE_HOME=str(tmp_path / "cache"))
    done = subprocess.run([SIGNORINI, "run", str(tmp_path / "c.yaml"), "--quiet"], env=env, capture_output=True,
                          text=True, timeout=600)
    assert (done.returncode, done.stdout, done.stderr) == (0, "", "")
    assert list((tmp_path / "cache" / "fenics").glob("*.so"))  # it did compile


# --- the API ----------------------------------------------------------------------------------------------

def test_api_runs_a_map_with_the_rows_of_the_cli(tmp_path):
    path = write_map(tmp_path, {"alpha": [1.5, 3]})
    assert cli.main(["run", path, "--quiet"]) == cli.EXIT_OK
    seen = []
    study = api_run(load(path, output__dir=str(tmp_path / "api")), on_level=lambda level, u_h: seen.append(level.n))
    assert not (tmp_path / "api").exists()  # no files without write=True
    assert seen == [2, 4, 2, 4]
    recorded = rows(tmp_path / "m")
    assert [row["status"] for row in study.rows] == ["complete"] * 2 and study.converged and study.met
    for row, csv_row in zip(study.rows, recorded):
        assert abs(row["L2"] - float(csv_row["L2"])) <= RTOL * row["L2"]


def test_api_write_honours_the_folder_lock(tmp_path):
    """run(cfg, write=True) into a folder a `signorini run` writes: refused (it used to overwrite rates.csv
    while the other run went on)."""
    cfg = load(merge(BASE, {"output": {"dir": str(tmp_path), "plots": False}}))
    with guard.FolderLock(tmp_path / "t", MPI.COMM_WORLD):
        with pytest.raises(ConfigError, match="is being written by another signorini run"):
            api_run(cfg, write=True)
        assert os.listdir(tmp_path / "t") == []
    assert api_run(cfg, write=True).rows and status(tmp_path / "t") == "complete"


@pytest.mark.mpi
@pytest.mark.parametrize("ranks_per_point", [1, 2])
def test_chunks_on_two_ranks_write_each_point_once(tmp_path_factory, ranks_per_point):
    """Chunks on 2 ranks (groups of 1 or 2): each group's rank 0 locks the points it takes; two chunks one
    after the other give the complete map, every point written by one group."""
    comm = MPI.COMM_WORLD
    assert comm.size == 2
    folder = Path(comm.bcast(str(tmp_path_factory.mktemp("chunks")) if comm.rank == 0 else None))
    path = write_map(folder / "cfg", {"alpha": [1.5, 2, 2.5, 3]}, map={"ranks_per_point": ranks_per_point}) \
        if comm.rank == 0 else None
    path = comm.bcast(path)
    cfg = load(path, output__dir=str(folder / "out"))
    first = maps.run(cfg, "0-2", quiet=True, comm=comm)
    second = maps.run(cfg, "3", quiet=True, comm=comm)
    assert maps.exit_status(first, comm) == 0 and maps.exit_status(second, comm) == 0
    taken = comm.allgather(sorted(p.index for p in first + second if p.comm.rank == 0))
    assert sorted(sum(taken, [])) == [0, 1, 2, 3]
    if comm.rank == 0:
        assert status(folder / "out" / "m") == "complete"
