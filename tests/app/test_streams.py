"""Output streams and signals around a run: a study's exit status is its own whatever happens to stdout and
stderr (a reader that leaves, a full device, a descriptor closed at start), printing that fails neither stops
nor fails it, SIGHUP ends it as SIGTERM does, and a signal during form compilation leaves the FFCx cache
usable."""
import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from signorini_cli.app import cli
from conftest import BASE, merge

SIGNORINI = str(Path(sys.executable).with_name("signorini"))


def write_config(folder, refinements=(4, 8, 16), **changes):
    path = Path(folder) / "c.yaml"
    path.write_text(yaml.safe_dump(merge(BASE, dict(changes, mesh={"refinements": list(refinements)},
                                                    output={"plots": False, "dir": str(Path(folder) / "out")}))))
    return str(path)


def status(folder):
    return (Path(folder) / "out" / "t" / "status.txt").read_text().strip()


def levels(folder):
    with open(Path(folder) / "out" / "t" / "rates.csv") as f:
        return [row["converged"] for row in csv.DictReader(f)]


@pytest.mark.parametrize("args, expected", [
    pytest.param([], cli.EXIT_OK, id="converged"),
    pytest.param(["-snes_max_it", "1"], cli.EXIT_NOT_CONVERGED, id="not-converged"),  # one step is not enough
])
def test_reader_leaves_after_one_line(tmp_path, args, expected):
    """`signorini run cfg 2>&1 | head -1`: the progress lines meet a closed pipe, the study goes on to its end
    and exits with its own status (a BrokenPipeError once made a stopped study exit 0)."""
    proc = subprocess.Popen([SIGNORINI, "run", write_config(tmp_path), *args], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT)
    proc.stdout.readline()
    proc.stdout.close()
    assert proc.wait(timeout=300) == expected
    assert levels(tmp_path) == ["true" if expected == cli.EXIT_OK else "false"] * 3
    assert status(tmp_path) == ("complete" if expected == cli.EXIT_OK else "complete: 0 of 3 levels converged")


def run_with(tmp_path, **streams):
    return subprocess.run([SIGNORINI, "run", write_config(tmp_path)], timeout=300, **streams)


def test_stdout_on_a_full_device(tmp_path):
    with open("/dev/full", "w") as full:
        done = run_with(tmp_path, stdout=full, stderr=subprocess.PIPE, text=True)
    assert done.returncode == cli.EXIT_OK and done.stderr.startswith("level 0"), done.stderr  # progress only
    assert "Traceback" not in done.stderr and "error" not in done.stderr, done.stderr
    assert status(tmp_path) == "complete"


def test_stderr_on_a_full_device(tmp_path):
    """The progress lines fail to print inside Newton's monitor: once a level 'did not converge' (exit 1)."""
    with open("/dev/full", "w") as full:
        done = run_with(tmp_path, stdout=subprocess.PIPE, stderr=full, text=True)
    assert done.returncode == cli.EXIT_OK and "wrote rates.md" in done.stdout
    assert levels(tmp_path) == ["true"] * 3 and status(tmp_path) == "complete"


@pytest.mark.parametrize("closed", [pytest.param((1,), id="stdout"), pytest.param((1, 2), id="stdout-stderr")])
def test_standard_descriptors_closed_at_start(tmp_path, closed):
    """`signorini run cfg >&-`: Python starts without sys.stdout; the run completes and no file it opens
    takes descriptor 1 (the table would have been printed into it)."""
    done = run_with(tmp_path, preexec_fn=lambda: [os.close(fd) for fd in closed], stderr=None if 2 in closed
                    else subprocess.PIPE)
    assert done.returncode == cli.EXIT_OK, done.stderr
    assert levels(tmp_path) == ["true"] * 3 and status(tmp_path) == "complete"
    for path in (tmp_path / "out" / "t").iterdir():  # the terminal's table ends "wrote rates.md, ..."
        assert b"wrote rates.md" not in path.read_bytes(), path


@pytest.mark.slow
def test_sigterm_while_forms_compile_leaves_the_cache_usable(tmp_path):
    """FFCx claims a form's cache entry with an empty .c file: a run killed while compiling left the claim,
    and every later run of that form waited 10 s and failed with a TimeoutError. Signals now wait until the
    compilation is done: every .c is complete (.c.cached beside it) and the same config runs again."""
    env = dict(os.environ, XDG_CACHE_HOME=str(tmp_path / "cache"))  # a fresh FFCx cache: level 0 compiles
    config = write_config(tmp_path)
    proc = subprocess.Popen([SIGNORINI, "run", config, "--quiet"], env=env, stderr=subprocess.PIPE, text=True)
    cache, started = tmp_path / "cache" / "fenics", time.monotonic()
    while not list(cache.glob("*.c")) and proc.poll() is None and time.monotonic() - started < 120:
        time.sleep(0.01)
    proc.send_signal(signal.SIGTERM)  # a compilation is under way
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signal.SIGTERM and err.count("\n") == 1, err
    claimed = sorted(path.name for path in cache.glob("*.c"))
    assert claimed and claimed == sorted(path.name.removesuffix(".cached") for path in cache.glob("*.c.cached"))
    done = subprocess.run([SIGNORINI, "run", config, "--quiet", "--force"], env=env, capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == cli.EXIT_OK and done.stderr == "", done.stderr
