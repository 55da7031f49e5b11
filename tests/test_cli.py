"""The command line: exit codes 0/1/2 and one-line errors naming the key."""
import csv

import yaml

from signorini_cli import cli
from conftest import BASE, merge


def write(tmp_path, **changes):
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(merge(BASE, dict(changes, output={"dir": str(tmp_path / "out")}))))
    return str(path)


def test_run_writes_table(tmp_path, capsys):
    assert cli.main(["run", write(tmp_path)]) == cli.EXIT_OK
    out = capsys.readouterr().out
    assert "rate_L2" in out and "study t" in out
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
    assert "No such file" in capsys.readouterr().err


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
    assert "verification: rates fitted over the last 3 levels" in out
    assert "expect H1 >= 3 - 0.1: NOT MET" in out
    with open(tmp_path / "out" / "t" / "summary.csv") as f:
        rows = {(r["kind"], r["name"]): r for r in csv.DictReader(f)}
    assert rows[("expect", "H1")]["met"] == "false" and rows[("norm", "H1")]["verdict"] == "agrees"


def test_expect_met_exit_0(tmp_path):
    path = write(tmp_path, mesh={"refinements": [4, 8]}, expect={"rates": {"H1": 0.5}})
    assert cli.main(["run", path, "--set", "output.plots=false"]) == cli.EXIT_OK
