"""The examples in docs/ run as written."""
import re
import runpy
from pathlib import Path

from mpi4py import MPI

from signorini_cli import studies
from signorini_cli.record import results

DOCS = Path(__file__).resolve().parents[2] / "docs"


def python_blocks(path):
    return re.findall(r"```python\n(.*?)```", path.read_text(), flags=re.S)


def test_results_format_h5py_example(make_config, tmp_path, monkeypatch, capsys):
    (example,) = python_blocks(DOCS / "results-format.md")
    assert len(example.strip().splitlines()) <= 12  # "a ~10-line h5py example"
    cfg = make_config(study="demo", output={"dir": str(tmp_path / "results")})
    results.write(studies.study_of(cfg, studies.run_study(cfg, comm=MPI.COMM_SELF)))
    script = tmp_path / "example.py"
    script.write_text(example)
    monkeypatch.chdir(tmp_path)  # the example opens results/demo/study.h5
    runpy.run_path(str(script), run_name="__main__")
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == "demo on 1 rank(s), dolfinx 0.5.2" and lines[1] == "alpha = 2.0  eps law: theta_h"
    assert [line.split()[0] for line in lines[2:]] == ["4", "8"]
    assert lines[3].endswith("Newton steps") and lines[2].split()[3] == "nan"  # no rate on level 0
