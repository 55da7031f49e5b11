"""Faults around a run: bad surroundings end with exit 2 and one line before any solve,
leaving nothing behind; a full disk mid-study leaves rates.csv and study.h5 with the same levels and a
status that says why; one run per study folder; SIGTERM ends gmsh meshing and the drawing of figures
cleanly; Ctrl-C while starting prints no traceback; a closed stdout ends the printing quietly; PETSc
options that no solver read are named."""
import csv
import errno
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import pytest
import yaml
from mpi4py import MPI

from signorini_cli.app import cli, guard
from signorini_cli.record import h5 as record_h5
from signorini_cli.report import tables
from signorini_cli.solve import solver
from conftest import BASE, merge, mounted

SIGNORINI = str(Path(sys.executable).with_name("signorini"))


def write_config(folder, refinements=(4, 8), **changes):
    path = Path(folder) / "c.yaml"
    path.write_text(yaml.safe_dump(merge(BASE, dict(changes, mesh={"refinements": list(refinements)},
                                                    output={"plots": False}))))  # figures cost ~2 s a run
    return str(path)


def levels_in(study):
    """(levels of rates.csv, levels_done of study.h5) of a study folder."""
    with open(Path(study) / "rates.csv") as f:
        rows = [row["level"] for row in csv.DictReader(f)]
    with h5py.File(Path(study) / "study.h5") as h5:
        return rows, int(h5.attrs["levels_done"])


def status(study):
    return (Path(study) / "status.txt").read_text().strip()


def tree(folder):
    return sorted(str(p.relative_to(folder)) for p in Path(folder).rglob("*"))




# --- class 2: bad surroundings -------------------------------------------------------------------

def test_read_only_output_folder_exit_2_one_line(tmp_path, capsys):
    config = write_config(tmp_path)
    with mounted(tmp_path / "ro", "ro,size=64k") as ro:
        assert cli.main(["run", config, "--output", str(ro / "results")]) == cli.EXIT_BAD_INPUT
        assert tree(ro) == []
    assert capsys.readouterr().err == (f"signorini: error: {config}: output.dir: {ro}/results: cannot write "
                                       "there: Read-only file system\n")


@pytest.mark.parametrize("target, named", [
    pytest.param("a-file", "a-file", id="output-is-a-file"),
    pytest.param("a-file/results", "a-file", id="output-under-a-file"),
    pytest.param("study-is-a-file", "study-is-a-file/t", id="study-folder-is-a-file"),
])
def test_output_not_a_folder_exit_2_nothing_left(tmp_path, capsys, target, named):
    config = write_config(tmp_path)
    (tmp_path / "a-file").write_text("")
    (tmp_path / "study-is-a-file").mkdir()
    (tmp_path / "study-is-a-file" / "t").write_text("")
    before = tree(tmp_path)
    assert cli.main(["run", config, "--output", str(tmp_path / target)]) == cli.EXIT_BAD_INPUT
    assert capsys.readouterr().err == (f"signorini: error: {config}: output.dir: {tmp_path / named} is "
                                       "not a folder\n")
    assert tree(tmp_path) == before


def test_refused_after_the_folder_was_made_leaves_nothing(tmp_path, capsys):
    """Bad input found once the study folder is made (the memory check of a 20000-cell-per-side
    level: 4e8 dofs): the folders made for the run are removed again."""
    config = write_config(tmp_path, refinements=(4, 20000))
    before = tree(tmp_path)
    assert cli.main(["run", config, "--output", str(tmp_path / "new" / "deeper")]) == cli.EXIT_BAD_INPUT
    assert capsys.readouterr().err.count("\n") == 1
    assert tree(tmp_path) == before


def test_data_refused_once_under_way_leaves_nothing(tmp_path, capsys):
    """Data found not finite as the first level is built (sin(r)/r at the origin): exit 2, one line, and no
    file behind (an empty rates.csv, study.h5 and a failed status made the corrected config need --force)."""
    config, out = write_config(tmp_path, problem={"exact": "sin(sqrt(x*x+y*y))/sqrt(x*x+y*y)"}), tmp_path / "out"
    assert cli.main(["run", config, "--output", str(out), "--quiet"]) == cli.EXIT_BAD_INPUT
    assert capsys.readouterr().err.startswith(f"signorini: error: {config}: problem.exact: ")
    assert not out.exists()
    fixed = write_config(tmp_path)
    assert cli.main(["run", fixed, "--output", str(out), "--quiet"]) == cli.EXIT_OK  # no --force needed


# --- class 2: a full disk mid-study --------------------------------------------------------------

def test_full_disk_mid_study_same_levels_and_status(tmp_path, monkeypatch, capsys):
    """study.h5 of level 2 finds the disk full (simulated): rates.csv and study.h5 both keep levels 0-1,
    status.txt says why (written in place, as the full disk refuses new files too), exit 2, one line."""
    config, out = write_config(tmp_path, refinements=(4, 8, 12)), tmp_path / "out"
    write_h5 = record_h5.write

    def full_at_level_2(path, attrs, *args, **kwargs):
        if attrs["levels_done"] >= 3:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        return write_h5(path, attrs, *args, **kwargs)
    monkeypatch.setattr(record_h5, "write", full_at_level_2)
    assert cli.main(["run", config, "--output", str(out), "--quiet"]) == guard.BAD_SURROUNDINGS
    assert capsys.readouterr().err == (f"signorini: error: {out}/t: cannot write the results: No space left "
                                       f"on device; failed at level 2: the 2 finished level(s) are in {out}/t; "
                                       "continue with --resume\n")
    assert status(out / "t") == "failed at level 2: No space left on device"
    assert levels_in(out / "t") == (["0", "1"], 2)
    assert not list((out / "t").glob(".*.tmp*"))
    monkeypatch.undo()
    assert cli.main(["run", config, "--output", str(out), "--resume", "--quiet"]) == cli.EXIT_OK
    assert status(out / "t") == "complete" and levels_in(out / "t") == (["0", "1", "2"], 3)


def test_full_disk_real_tmpfs_no_petsc_banner(tmp_path):
    """A 100 KiB tmpfs fills up after a level or two (study.h5 grows ~20 KiB a level): exit 2, no PETSc
    SEGV banner (HDF5 never meets the full disk: study.h5 is built in memory), the same levels in
    rates.csv and study.h5."""
    config = write_config(tmp_path, refinements=(4, 8, 16, 32, 64, 96))
    with mounted(tmp_path / "small", "size=100k") as small:
        done = subprocess.run([SIGNORINI, "run", config, "--output", str(small), "--quiet"],
                              capture_output=True, text=True, timeout=300)
        assert done.returncode == guard.BAD_SURROUNDINGS, done.stderr
        assert "PETSC ERROR" not in done.stderr and "Traceback" not in done.stderr, done.stderr
        assert done.stderr.count("\n") == 1, done.stderr
        rows, levels_done = levels_in(small / "t")
        assert len(rows) == levels_done < 6
        assert status(small / "t") == f"failed at level {levels_done}: No space left on device"


# --- class 5: one run per study folder -----------------------------------------------------------

def test_second_run_refused_while_the_folder_is_locked(tmp_path, capsys):
    config, out = write_config(tmp_path), tmp_path / "out"
    with guard.FolderLock(out / "t", MPI.COMM_WORLD):  # what a running study holds
        assert cli.main(["run", config, "--output", str(out), "--force"]) == cli.EXIT_BAD_INPUT
        assert tree(out) == ["t"]  # nothing written into the other run's folder
    assert capsys.readouterr().err == (f"signorini: error: {config}: output.dir: {out}/t is being written by "
                                       "another signorini run; wait for it to end or choose another output "
                                       "folder\n")
    assert cli.main(["run", config, "--output", str(out), "--quiet"]) == cli.EXIT_OK  # released


def test_lock_of_a_killed_run_is_no_obstacle(tmp_path):
    """kill -9 of the holder: the kernel drops its flock, the next run goes ahead."""
    config, out = write_config(tmp_path), tmp_path / "out"
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from mpi4py import MPI; "
                               "from signorini_cli.app import guard; guard.FolderLock(sys.argv[1], MPI.COMM_WORLD); "
                               "print('held', flush=True); time.sleep(600)", str(out / "t")],
                              stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline() == "held\n"
    assert cli.main(["run", config, "--output", str(out), "--quiet"]) == cli.EXIT_BAD_INPUT
    holder.kill()
    holder.wait()
    assert cli.main(["run", config, "--output", str(out), "--quiet"]) == cli.EXIT_OK


def test_two_runs_at_once_one_refused(tmp_path):
    """Two configs into one folder at the same time: the second refuses (exit 2), the first's results stay."""
    first, out = write_config(tmp_path, refinements=(4, 8, 16, 32, 64, 128)), tmp_path / "out"
    other = tmp_path / "other"
    other.mkdir()
    second = write_config(other, epsilon={"law": "theta_h", "theta": 2.0})
    proc = subprocess.Popen([SIGNORINI, "run", first, "--output", str(out), "--quiet"], stderr=subprocess.PIPE,
                            text=True)
    started = time.monotonic()
    while not (out / "t" / "status.txt").exists() and proc.poll() is None and time.monotonic() - started < 120:
        time.sleep(0.02)  # the first run holds the lock once status.txt exists
    code = cli.main(["run", second, "--output", str(out), "--force", "--quiet"])
    assert proc.wait(timeout=300) == cli.EXIT_OK, proc.stderr.read()
    assert code == cli.EXIT_BAD_INPUT
    assert status(out / "t") == "complete" and levels_in(out / "t") == ([str(k) for k in range(6)], 6)


# --- class 4: signals ----------------------------------------------------------------------------

def test_sigterm_while_drawing_figures_is_not_complete(tmp_path, monkeypatch, capsys):
    """status.txt says complete only once the tables and figures are written; SIGTERM while they are
    drawn leaves 'interrupted while writing tables and figures', and --resume completes them."""
    config, out = write_config(tmp_path), tmp_path / "out"
    write, seen = tables.write, []

    def write_then_signal(*args, **kwargs):
        seen.append(status(out / "t"))
        os.kill(os.getpid(), signal.SIGTERM)
        return write(*args, **kwargs)
    monkeypatch.setattr(tables, "write", write_then_signal)
    assert cli.main(["run", config, "--output", str(out), "--quiet"]) == 128 + signal.SIGTERM
    assert seen == ["running (2 of 2 levels done)"]
    assert status(out / "t") == "interrupted while writing tables and figures (all 2 levels done)"
    assert capsys.readouterr().err == ("signorini: interrupted by SIGTERM while writing tables and figures "
                                       f"(all 2 levels done): the 2 finished level(s) are in {out}/t; continue "
                                       "with --resume\n")
    monkeypatch.undo()
    assert cli.main(["run", config, "--output", str(out), "--resume", "--quiet"]) == cli.EXIT_OK
    assert status(out / "t") == "complete" and (out / "t" / "rates.md").exists()


def test_sigterm_while_gmsh_meshes_ends_it(tmp_path):
    """gmsh meshes in C, where no Python handler runs: it meshes in a child process that SIGTERM kills.
    The unit cube at size 0.02: SIGTERM 1 s into its meshing ended the run 36 s later before (gmsh meshed
    on), 0.4 s later now (measured); the 20 s limit tells them apart."""
    cache = tmp_path / "cache"
    config = tmp_path / "c.yaml"
    config.write_text(yaml.safe_dump(merge(BASE, {
        "dimension": 3, "contact": "contact", "output": {"plots": False},
        "problem": {"exact": "sin(2*pi*x)*(1-z)**2"},
        "mesh": {"kind": "gmsh", "geometry": "unit_cube", "sizes": [0.02], "cache": str(cache), "refinements": None}})))
    proc = subprocess.Popen([SIGNORINI, "run", str(config), "--output", str(tmp_path / "out"), "--force",
                             "--quiet"], stderr=subprocess.PIPE, text=True)
    started = time.monotonic()
    while not list(cache.glob(".*.tmp.msh")) and proc.poll() is None and time.monotonic() - started < 120:
        time.sleep(0.02)  # the temporary .msh appears as gmsh starts
    time.sleep(1.0)  # into the volume meshing
    proc.send_signal(signal.SIGTERM)
    try:
        _, err = proc.communicate(timeout=20)
    finally:
        proc.kill()
    assert proc.returncode == 128 + signal.SIGTERM and err == "signorini: interrupted by SIGTERM\n", err
    assert tree(cache) == []  # neither a mesh nor a temporary file left in the cache


@pytest.mark.parametrize("delay", [0.08, 0.15, 0.3])
def test_ctrl_c_while_starting_no_traceback(tmp_path, delay):
    """SIGINT in the first moments (modules loading, MPI starting): one line or none, exit 130."""
    # started as from a terminal: a suite launched in the background (nohup, `&`) ignores SIGINT, and the
    # child would inherit that until the run installs its own handler
    proc = subprocess.Popen([SIGNORINI, "run", write_config(tmp_path), "--output", str(tmp_path / "out")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    time.sleep(delay)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    # Python's own start-up (site.py, finding the package: the first ~60 ms here) runs no code of ours yet
    if "init_import_site" in err or ("Traceback" in err and "/signorini_cli/" not in err):
        pytest.skip(f"SIGINT after {delay} s came during Python's own start-up under this load")
    # -SIGINT: the signal came before Python's own handler was in place (the default action, also no traceback)
    assert proc.returncode in (128 + signal.SIGINT, -signal.SIGINT), err
    assert "Traceback" not in err and err.count("\n") <= 1, err


# --- class 7: a closed stdout --------------------------------------------------------------------

def test_closed_stdout_quiet_and_files_complete(tmp_path):
    """`signorini run cfg | head -1`, made certain: stdout is closed before anything is printed."""
    config, out = write_config(tmp_path), tmp_path / "out"
    proc = subprocess.Popen([SIGNORINI, "run", config, "--output", str(out)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    proc.stdout.close()
    err = proc.stderr.read()
    assert proc.wait(timeout=120) == cli.EXIT_OK, err
    assert "PETSC ERROR" not in err and "Broken" not in err and "Traceback" not in err, err
    assert status(out / "t") == "complete"
    assert (out / "t" / "rates.md").read_text().count("\n") >= 4  # header, rule and both levels


@pytest.mark.parametrize("command", [pytest.param(["list"], id="list"), pytest.param(["report"], id="report")])
def test_closed_stdout_other_commands_quiet(tmp_path, command):
    """`signorini list | head -1`, `signorini report STUDY | head -1`: exit 0, no BrokenPipeError traceback."""
    if command == ["report"]:
        assert cli.main(["run", write_config(tmp_path), "--output", str(tmp_path / "out"), "--quiet"]) == 0
        command = ["report", str(tmp_path / "out" / "t"), "--no-plots"]
    proc = subprocess.Popen([SIGNORINI, *command], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    proc.stdout.close()
    err = proc.stderr.read()
    assert proc.wait(timeout=120) == cli.EXIT_OK and err == "", err


# --- class 1: PETSc options nobody read ----------------------------------------------------------

@pytest.mark.parametrize("options, unused", [
    pytest.param({"ksp_gmres_restart": 50}, ["ksp_gmres_restart"], id="gmres-option-with-lu"),
    pytest.param({"pc_hypre_boomeramg_strong_threshold": 0.5, "snes_linesearch_type": "bt"},
                 ["pc_hypre_boomeramg_strong_threshold"], id="hypre-option-with-lu"),
    pytest.param({"snes_linesearch_type": "bt"}, [], id="all-used"),
])
def test_unused_petsc_options_are_named(tmp_path, capsys, options, unused):
    """Levels of at most 81 dofs are solved by LU (solver.DIRECT_MAX_DOFS_2D): a GMRES or hypre option
    is then never read by PETSc; the run names it in one warning after its first level."""
    config = write_config(tmp_path, solver={"petsc_options": options})
    assert cli.main(["run", config, "--output", str(tmp_path / "out"), "--quiet"]) == cli.EXIT_OK
    expected = (f"WARNING signorini_cli.app.commands: solver.petsc_options: {', '.join(unused)} not used by PETSc in "
                "level 0 (misspelt, or not an option of the solver and preconditioner in use)\n") if unused else ""
    assert capsys.readouterr().err == expected


def test_unused_options_of_a_destroyed_solver():
    """The record survives the solver: its options are cleared on destroy, PETSc's 'used' flag with them."""
    from petsc4py import PETSc
    opts = PETSc.Options()
    opts["signorini_test_ksp_type"] = "cg"
    opts["signorini_test_ksp_gmres_restart"] = "5"
    ksp = PETSc.KSP().create(MPI.COMM_SELF)
    ksp.setOptionsPrefix("signorini_test_")
    ksp.setFromOptions()
    assert solver.unused_options(["ksp_type", "ksp_gmres_restart"]) == ["ksp_gmres_restart"]
    ksp.destroy()
    solver._clear_options("signorini_test_")
    assert "signorini_test_ksp_type" not in opts.getAll()
    assert solver.unused_options(["ksp_type", "ksp_gmres_restart"]) == ["ksp_gmres_restart"]
