"""The command line: exit codes 0/1/2 and one-line errors naming the key."""
import csv
import importlib.metadata
import os

from pathlib import Path

import pytest
import yaml

from signorini_cli import config
from signorini_cli.app import cli
from conftest import BASE, merge


def write(tmp_path, **changes):
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(merge(BASE, dict(changes, output={"dir": str(tmp_path / "out")}))))
    return str(path)


def test_run_writes_table(tmp_path, capsys):
    assert cli.main(["run", write(tmp_path)]) == cli.EXIT_OK
    out = capsys.readouterr().out
    assert "L²" in out and "rate" in out and "study t" in out  # the grouped table: each norm, error | rate
    assert (tmp_path / "out" / "t" / "study.h5").exists()


def test_bad_value_exit_2_one_line(tmp_path, capsys):
    path = write(tmp_path, epsilon={"theta": -1})
    assert cli.main(["run", path]) == cli.EXIT_BAD_INPUT
    err = capsys.readouterr().err.strip()
    assert err == f"signorini: error: {path}: epsilon.theta: must be > 0, got -1"


def test_bad_override_exit_2(tmp_path, capsys):
    assert cli.main(["run", write(tmp_path), "--set", "alpha=0"]) == cli.EXIT_BAD_INPUT
    assert "alpha: must be >= 1, got 0" in capsys.readouterr().err


def test_yaml_syntax_error_names_line(tmp_path, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text("study: x\nmesh: [unclosed\n")
    assert cli.main(["run", str(path)]) == cli.EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert "YAML syntax error: line 3, column 1" in err and "Traceback" not in err


def test_missing_file_exit_2(tmp_path, capsys):
    assert cli.main(["run", str(tmp_path / "none.yaml")]) == cli.EXIT_BAD_INPUT
    assert "none.yaml: no such file or directory" in capsys.readouterr().err


def test_existing_results_need_force(tmp_path, capsys):
    path = write(tmp_path)
    assert cli.main(["run", path]) == cli.EXIT_OK
    assert cli.main(["run", path]) == cli.EXIT_BAD_INPUT
    assert "--force" in capsys.readouterr().err
    assert cli.main(["run", path, "--force"]) == cli.EXIT_OK


def test_unconverged_level_exit_1(tmp_path):
    path = write(tmp_path, solver={"max_it": 1})
    assert cli.main(["run", path]) == cli.EXIT_NOT_CONVERGED
    with open(tmp_path / "out" / "t" / "rates.csv") as f:
        rows = list(csv.DictReader(f))
    assert [row["converged"] for row in rows] == ["false", "false"]
    assert rows[0]["L2"] == "" and rows[0]["reason"] == "DIVERGED_MAX_IT"


def test_output_flag_overrides_dir(tmp_path):
    assert cli.main(["run", write(tmp_path), "--output", str(tmp_path / "elsewhere")]) == cli.EXIT_OK
    assert (tmp_path / "elsewhere" / "t" / "rates.csv").exists()


def test_expect_missed_exit_1_with_verdict(tmp_path, capsys):
    path = write(tmp_path, mesh={"refinements": [4, 8]}, expect={"rates": {"H1": 3.0}})
    assert cli.main(["run", path, "--set", "output.plots=false"]) == cli.EXIT_EXPECTATION_NOT_MET
    out = capsys.readouterr().out
    assert "verification: rate = slope of log e against log h over the last 3 levels" in out
    assert "expect H1 >= 3 - 0.1: NOT MET" in out
    with open(tmp_path / "out" / "t" / "summary.csv") as f:
        rows = {(r["kind"], r["name"]): r for r in csv.DictReader(f)}
    # two levels give a slope but no verdict: too few to tell how settled it is
    assert rows[("expect", "H1")]["met"] == "false" and rows[("norm", "H1")]["verdict"] == "inconclusive"


def test_expect_met_exit_0(tmp_path):
    path = write(tmp_path, mesh={"refinements": [4, 8]}, expect={"rates": {"H1": 0.5}})
    assert cli.main(["run", path, "--set", "output.plots=false"]) == cli.EXIT_OK


def test_version(capsys):
    import dolfinx
    with pytest.raises(SystemExit) as done:
        cli.main(["--version"])
    assert done.value.code == 0
    # the installed distribution's metadata, not the package's own __version__ string
    expected = f"signorini {importlib.metadata.version('signorini-cli')} (dolfinx {dolfinx.__version__})\n"
    assert capsys.readouterr().out == expected


def test_help_names_the_config_docs(capsys):
    with pytest.raises(SystemExit):
        cli.main(["run", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    # documentation there wherever the package is installed: the init command, not a path of the repository
    assert "docs/" not in out and "signorini init" in out and "-snes_monitor" in out


def test_init_says_what_it_wrote(tmp_path, capsys):
    assert cli.main(["init", str(tmp_path / "c.yaml")]) == cli.EXIT_OK
    assert capsys.readouterr().out.startswith(f"wrote {tmp_path / 'c.yaml'}: every config key at its default")


def test_missing_config_one_line_without_errno(capsys):
    assert cli.main(["run", "/nonexistent/c.yaml"]) == cli.EXIT_BAD_INPUT
    assert capsys.readouterr().err == "signorini: error: /nonexistent/c.yaml: no such file or directory\n"


def test_did_you_mean_on_a_value(capsys):
    root = Path(__file__).resolve().parents[2]
    assert cli.main(["check", str(root / "configs/demo.yaml"), "--set", "epsilon.law=theta-h"]) == cli.EXIT_BAD_INPUT
    assert "'theta-h' is not one of theta_h, " in capsys.readouterr().err.replace("\n", " ")
    assert cli.main(["check", str(root / "configs/demo.yaml"), "--set", "epsilon.law=theta-h"]) == cli.EXIT_BAD_INPUT
    assert "(did you mean 'theta_h'?)" in capsys.readouterr().err


def test_petsc_options_on_the_command_line(tmp_path, capsys):
    """After the config or after `--`, recorded in the resolved config as solver.petsc_options are."""
    argv = ["check", write(tmp_path), "-snes_monitor", "-ksp_rtol", "1e-8", "--", "-snes_lag_preconditioner", "-2"]
    assert cli.main(argv) == cli.EXIT_OK
    resolved = yaml.safe_load(capsys.readouterr().out)
    assert resolved["solver"]["petsc_options"] == {"snes_monitor": "", "ksp_rtol": "1e-8",
                                                   "snes_lag_preconditioner": "-2"}


def test_petsc_option_reaches_the_solver(tmp_path):
    """-snes_max_it 1 under the study's prefix stops Newton after one step, as solver.max_it: 1 does."""
    assert cli.main(["run", write(tmp_path), "--set", "output.plots=false", "-snes_max_it", "1"]) == \
        cli.EXIT_NOT_CONVERGED
    with open(tmp_path / "out" / "t" / "rates.csv") as f:
        assert [row["reason"] for row in csv.DictReader(f)] == ["DIVERGED_MAX_IT"] * 2


@pytest.mark.parametrize("args, message", [
    pytest.param(["-snes_max_it", "abc"], "solver.petsc_options.snes_max_it: must be an integer, got 'abc'",
                 id="type"),
    pytest.param(["-snes_type", "ksponly"], "solver.petsc_options.snes_type: the study chooses the SNES type",
                 id="ksponly"),
    pytest.param(["--", "stray"], "--: 'stray' is not a PETSc option", id="stray"),
])
def test_bad_petsc_option_on_the_command_line_exit_2(tmp_path, capsys, args, message):
    path = write(tmp_path)
    assert cli.main(["run", path, *args]) == cli.EXIT_BAD_INPUT
    assert capsys.readouterr().err.startswith(f"signorini: error: {path}: {message}")
    assert not (tmp_path / "out").exists()


def test_init_writes_a_valid_commented_config(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert cli.main(["init", "new.yaml"]) == cli.EXIT_OK
    assert config.load("new.yaml").solver == config.Solver()
    assert cli.main(["init", "new.yaml"]) == cli.EXIT_BAD_INPUT
    assert "new.yaml: already exists; use --force" in capsys.readouterr().err
    assert cli.main(["init"]) == cli.EXIT_OK
    assert capsys.readouterr().out == (tmp_path / "new.yaml").read_text()


@pytest.mark.parametrize("exact", ["5", "0*x", "eps"])
def test_constant_manufactured_solution_runs(tmp_path, exact):
    """u = const lies in V_h (P1 reproduces it): the errors are round-off, far below 1e-10."""
    path = write(tmp_path, problem={"exact": exact}, mesh={"refinements": [2, 4]})
    assert cli.main(["run", path, "--set", "output.plots=false"]) == cli.EXIT_OK
    with open(tmp_path / "out" / "t" / "rates.csv") as f:
        rows = list(csv.DictReader(f))
    assert [row["converged"] for row in rows] == ["true", "true"]
    assert all(float(row["L2"]) < 1e-10 and float(row["H1"]) < 1e-10 for row in rows)


def test_config_from_a_fifo_exit_2_at_once(tmp_path, capsys):
    fifo = tmp_path / "config.yaml"
    os.mkfifo(fifo)
    assert cli.main(["run", str(fifo)]) == cli.EXIT_BAD_INPUT  # would block forever on a plain open()
    assert capsys.readouterr().err == f"signorini: error: {fifo}: not a regular file (a config is read from a " \
                                      "file, not a folder, FIFO or device)\n"
