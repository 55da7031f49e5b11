"""The bad-input corpus tests/config/bad_input/: every config exits 2 with its one expected line and no
traceback, serially and on 2 ranks (one line, from rank 0)."""
import collections
import os
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from mpi4py import MPI

from signorini_cli.app import cli

pytestmark = pytest.mark.fast

CORPUS = sorted((Path(__file__).parent / "bad_input").glob("*.yaml"))
parametrize_corpus = pytest.mark.parametrize("path", CORPUS, ids=[p.stem for p in CORPUS])


def case(path):
    """(expected message, extra CLI arguments) from the '# expect:' and '# args:' header lines."""
    header = path.read_bytes().decode("utf-8", errors="replace").splitlines()[:2]
    expected = header[0].removeprefix("# expect: ")
    args = header[1].removeprefix("# args: ") if len(header) > 1 and header[1].startswith("# args: ") else ""
    return expected, shlex.split(args)


def expected_line(path):
    return f"signorini: error: {path}: {case(path)[0]}\n"


def counts_line():
    """How docs/guide/config.md states the corpus: its size and the cases per kind (the file names' first word)."""
    kinds = collections.Counter(path.stem.split("-")[0] for path in CORPUS)
    return (f"`tests/config/bad_input/` holds {len(CORPUS)} bad configs "
            f"({', '.join(f'{kind} {n}' for kind, n in sorted(kinds.items()))})")


def test_readme_states_the_corpus_counts():
    """The counts in docs/guide/config.md are this run's: a changed corpus fails here with the line to put there."""
    readme = " ".join((Path(__file__).parents[2] / "docs/guide/config.md").read_text().split())
    assert counts_line() in readme, f"docs/guide/config.md should say: {counts_line()}"


def test_corpus_cases_are_distinct_and_state_their_message():
    """Every case states the one line it must get (its first line) and no case repeats another."""
    texts = [path.read_bytes() for path in CORPUS]
    assert len(set(texts)) == len(texts), "a case repeats another"
    for path in CORPUS:
        assert path.read_bytes().startswith(b"# expect: ") and case(path)[0].strip(), path.name


@parametrize_corpus
def test_bad_input_exits_2_with_one_line(path, capsys, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)  # a case that wrongly passed would write its results here
    assert cli.main(["run", str(path), *case(path)[1]]) == cli.EXIT_BAD_INPUT
    captured = capsys.readouterr()
    assert captured.err == expected_line(path)
    assert captured.out == ""


@pytest.mark.mpi
def test_bad_input_two_ranks_one_line(capsys, monkeypatch, tmp_path_factory):
    comm = MPI.COMM_WORLD
    assert comm.size == 2
    monkeypatch.chdir(tmp_path_factory.mktemp(f"rank{comm.rank}"))
    failures = []
    for path in CORPUS:
        code = cli.main(["run", str(path), *case(path)[1]])
        err = capsys.readouterr().err
        codes, errs = comm.allgather(code), comm.allgather(err)
        if codes != [2, 2] or errs != [expected_line(path), ""]:
            failures.append((path.name, codes, errs))
    assert not failures  # the same list on both ranks: they pass or fail together


@pytest.mark.skipif(shutil.which("mpirun") is None, reason="needs mpirun")
def test_bad_input_mpirun_exit_2_one_line():
    """The real thing: `mpirun -q -n 2 signorini run BAD.yaml` (-q: no Open MPI banner) prints one line."""
    path = Path(__file__).parent / "bad_input" / "range-alpha-above-3-in-3d.yaml"
    exe = str(Path(sys.executable).with_name("signorini"))
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    done = subprocess.run(["mpirun", "-q", "-n", "2", exe, "run", str(path)], capture_output=True, text=True,
                          env=env, timeout=120)
    assert done.returncode == cli.EXIT_BAD_INPUT
    assert done.stderr == expected_line(path) and done.stdout == ""
