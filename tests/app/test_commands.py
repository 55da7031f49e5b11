"""check, list, report and compare from the command line; run's --quiet and --verbose."""
import re
import subprocess
import sys

import pytest
import yaml

from signorini_cli import config, studies
from signorini_cli.app import cli, commands
from signorini_cli.record import csvfile, results
from conftest import BASE, merge


def write(tmp_path, name="c.yaml", **changes):
    path = tmp_path / name
    raw = merge(BASE, {"output": {"dir": str(tmp_path / "out")}})
    path.write_text(yaml.safe_dump(merge(raw, changes)))
    return str(path)


def test_check_prints_every_default(tmp_path, capsys):
    assert cli.main(["check", write(tmp_path)]) == cli.EXIT_OK
    out = capsys.readouterr().out
    resolved = yaml.safe_load(out)
    # keys the file does not give, filled in with their defaults
    assert resolved["solver"] == {"rtol": 1e-10, "atol": 1e-12, "max_it": 50, "linear": "auto",
                                  "line_search": "bt", "on_failure": "continue", "petsc_options": {},
                                  "strategy": "auto", "method": "newtonls", "stol": 1e-7,
                                  "preconditioner": "boomeramg", "linear_rtol": 1e-10, "linear_fallback": True,
                                  "inexact": False, "continuation": {"start": 1.0, "factor": 0.1, "max_steps": 20},
                                  "condition_max_dofs": 0, "linear_floor": False, "polish": 3}
    assert resolved["output"]["plots"] is True and resolved["output"]["fields"] is False
    assert resolved["positive_part"] == {"kind": "exact"} and resolved["mesh"]["diagonal"] == "right"
    assert "refinements: [4, 8]" in out
    assert config.to_dict(config.from_dict(resolved)) == resolved  # the printout is a valid config


def test_check_applies_set_and_output(tmp_path, capsys):
    args = ["check", write(tmp_path), "--set", "epsilon.theta=10", "--set", "solver.petsc_options={a: 1}",
            "--output", str(tmp_path / "o")]
    assert cli.main(args) == cli.EXIT_OK
    resolved = yaml.safe_load(capsys.readouterr().out)
    assert resolved["epsilon"]["theta"] == 10.0 and resolved["solver"]["petsc_options"] == {"a": "1"}
    assert resolved["output"]["dir"] == str(tmp_path / "o")


@pytest.mark.parametrize("override, message", [
    pytest.param("alpha=0", "alpha: must be >= 1, got 0", id="range"),
    pytest.param("epsilon.law=thetah", "epsilon.law: 'thetah' is not one of theta_h", id="choice"),
    pytest.param("solver.rtl=1e-8", "solver.rtl: unknown key in solver (did you mean 'solver.rtol'?)", id="typo"),
    pytest.param("alpha.x=1", "alpha: is not a mapping, cannot set a sub-key", id="not-mapping"),
    pytest.param("alpha", "--set: expected KEY=VALUE, got 'alpha'", id="no-equals"),
    pytest.param("output.plots=maybe", "output.plots: must be true or false, got str 'maybe'", id="bool"),
    pytest.param("mesh.refinements=[8, 4]", "mesh.refinements: must increase, got [8, 4]", id="order"),
])
@pytest.mark.parametrize("command", ["check", "run"])
def test_set_validation_errors(tmp_path, capsys, command, override, message):
    path = write(tmp_path)
    assert cli.main([command, path, "--set", override]) == cli.EXIT_BAD_INPUT
    captured = capsys.readouterr()
    assert captured.err.startswith(f"signorini: error: {path}: {message}")
    assert captured.err.count("\n") == 1 and "Traceback" not in captured.err
    assert not (tmp_path / "out").exists()  # nothing ran


def test_list_shows_descriptions(tmp_path, capsys):
    (tmp_path / "paper").mkdir()
    write(tmp_path / "paper", "a.yaml", description="first study")
    (tmp_path / "bad.yaml").write_text("study: x\n")
    assert cli.main(["list", str(tmp_path)]) == cli.EXIT_OK
    lines = capsys.readouterr().out.splitlines()
    # paths that `run` takes: tmp_path lies outside the working folder, so absolute
    assert lines[0].startswith(f"{tmp_path}/bad.yaml") and "(invalid: mesh: missing required key)" in lines[0]
    assert lines[1].split(None, 1) == [f"{tmp_path}/paper/a.yaml", "first study"]


def test_list_shipped_configs(capsys):
    assert cli.main(["list"]) == cli.EXIT_OK
    out = capsys.readouterr().out
    assert "demo.yaml" in out and "(invalid" not in out and "(no description)" not in out


class Interrupt(Exception):
    pass


def stop_after(cfg, k):
    def write_then_stop(levels):
        results.write(studies.study_of(cfg, levels))
        if len(levels) == k:
            raise Interrupt
    with pytest.raises(Interrupt):
        studies.run_study(cfg, on_level=write_then_stop)


def test_report_partial_study(make_config, capsys):
    cfg = make_config(mesh={"refinements": [4, 8, 16]})
    stop_after(cfg, 2)  # killed during its third level
    folder = cfg.output_dir
    assert cli.main(["report", str(folder), "--digits", "2"]) == cli.EXIT_OK
    out = capsys.readouterr().out
    assert out.startswith("study t: 2 of 3 levels (partial study)")
    assert out.splitlines()[2].split()[-3:] == ["error", "rate", "time"] and "wrote into" in out
    table = (folder / "rates.md").read_text().splitlines()
    # comment, header, rule, 2 levels; h = 1.41/N is left out, so ε (= h) follows N; then the recorded verdict
    assert table[4].startswith("| 8 | 1.77e-01 |") and table[5:7] == ["", "| norm | observed | interval | "
                                                                          "proven | verdict | why |"]
    assert "too few levels: 2 converged in the fit, 3 needed" in " ".join(out.split())  # wrapped at 120
    assert r"\toprule" in (folder / "rates.tex").read_text()
    for name in ("convergence", "work_precision", "newton"):
        assert (folder / f"{name}.png").stat().st_size > 0 and (folder / f"{name}.pdf").exists()


def test_report_from_csv_only_no_plots(make_config, tmp_path, capsys):
    cfg = make_config()
    stop_after(cfg, 1)
    (cfg.output_dir / "study.h5").unlink()
    out_dir = tmp_path / "elsewhere"
    args = ["report", str(cfg.output_dir / "rates.csv"), "--no-plots", "--output", str(out_dir)]
    assert cli.main(args) == cli.EXIT_OK
    assert capsys.readouterr().out.startswith("study t: 1 level from")
    assert sorted(p.name for p in out_dir.iterdir()) == ["rates.md", "rates.tex"]


def test_report_not_a_study_exit_2(tmp_path, capsys):
    assert cli.main(["report", str(tmp_path)]) == cli.EXIT_BAD_INPUT
    assert "not a study folder" in capsys.readouterr().err


def test_compare_two_studies(make_config, tmp_path, capsys):
    for theta in (1, 10):
        cfg = make_config(study=f"theta{theta}", epsilon={"theta": theta})
        results.write(studies.study_of(cfg, studies.run_study(cfg)))
    folders = [str(tmp_path / "results" / f"theta{t}") for t in (1, 10)]
    assert cli.main(["compare", *folders]) == cli.EXIT_OK
    out = capsys.readouterr().out
    assert [line.split()[0] for line in out.splitlines()[2:4]] == ["theta1", "theta10"]  # under 2 header lines
    compared = tmp_path / "results" / "compare-theta1-theta10"  # named for its inputs: another compare goes beside
    assert (compared / "compare_convergence.pdf").exists()
    table = (compared / "compare.csv").read_text().splitlines()
    assert table[0].startswith("study,levels,finest_h,time_s,L2_finest,L2_fit,H1_finest,H1_fit")
    assert [line.split(",")[0] for line in table[1:]] == ["theta1", "theta10"]
    assert r"\label{tab:compare}" in (compared / "compare.tex").read_text() and (compared / "compare.md").exists()
    assert cli.main(["compare", *folders, "--label", "one"]) == cli.EXIT_BAD_INPUT
    assert "--label: give one per study" in capsys.readouterr().err


def test_report_shows_the_verdict_run_recorded(tmp_path, capsys):
    """report redraws a study with the verdict its run decided: the same block on the terminal, the same
    rates.md (verdict lines included)."""
    path = write(tmp_path, output={"plots": False}, mesh={"refinements": [4, 8, 16]})
    assert cli.main(["run", path]) == cli.EXIT_OK
    ran = capsys.readouterr().out
    folder = tmp_path / "out" / "t"
    written = (folder / "rates.md").read_text()
    (folder / "rates.md").unlink()
    assert cli.main(["report", str(folder), "--no-plots"]) == cli.EXIT_OK
    reported = capsys.readouterr().out
    block = ran[ran.index("verification:"):ran.index("wrote")]
    assert "agrees" in block and block in reported
    assert (folder / "rates.md").read_text() == written


def test_compare_shows_the_rate_run_shows(make_config, tmp_path):
    """The same study's rate in summary.csv (the verdict's) and in compare.csv: one fit, over the study's own
    verification.fit_levels (here 2, not the default 3)."""
    for k in (2, 3):
        cfg = make_config(study=f"fit{k}", mesh={"refinements": [4, 8, 16]}, verification={"fit_levels": k})
        results.write(studies.study_of(cfg, studies.run_study(cfg)))
    folders = [tmp_path / "results" / f"fit{k}" for k in (2, 3)]
    assert cli.main(["compare", *map(str, folders), "--output", str(tmp_path / "c")]) == cli.EXIT_OK
    fits = {row["study"]: row["L2_fit"] for row in csvfile.read(tmp_path / "c" / "compare.csv")}
    for k, folder in zip((2, 3), folders):
        (l2,) = [row for row in csvfile.read(folder / "summary.csv") if row["name"] == "L2"]
        assert fits[f"fit{k}"] == l2["observed_rate"]
    assert fits["fit2"] != fits["fit3"]
    assert "each study's last verification.fit_levels levels" in (tmp_path / "c" / "compare.tex").read_text()


@pytest.mark.parametrize("labels", [["X", "X"], None])
def test_compare_refuses_one_label_for_two_studies(make_config, tmp_path, capsys, labels):
    cfg = make_config()
    results.write(studies.study_of(cfg, studies.run_study(cfg)))
    folder = str(cfg.output_dir)
    args = ["compare", folder, folder if labels is None else str(tmp_path / "results" / "t")]
    args += [f"--label={label}" for label in labels or []]
    assert cli.main(args + ["--output", str(tmp_path / "c")]) == cli.EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "names two of the studies" in err and not (tmp_path / "c").exists()


def test_run_progress_and_quiet(tmp_path, capsys):
    path = write(tmp_path, output={"plots": False})
    assert cli.main(["run", path]) == cli.EXIT_OK
    captured = capsys.readouterr()
    assert [line.split()[:2] for line in captured.err.splitlines()] == [["level", "0"], ["level", "1"]]
    assert "(rate " in captured.err.splitlines()[1] and "study t" in captured.out
    assert cli.main(["run", path, "--force", "--quiet"]) == cli.EXIT_OK
    assert capsys.readouterr() == ("", "")


def test_run_verbose_adds_petsc_monitors(make_config):
    cfg = commands.with_monitors(make_config(solver={"petsc_options": {"snes_monitor": "draw"}}))
    options = dict(cfg.solver.petsc_options)
    assert options["snes_monitor"] == "draw" and "ksp_converged_reason" in options  # the user's option wins


def test_report_columns_and_width_options(make_config, capsys):
    cfg = make_config()
    stop_after(cfg, 2)
    folder = cfg.output_dir
    assert cli.main(["report", str(folder), "--columns", "all", "--width", "6in", "--per-norm"]) == cli.EXIT_OK
    out = capsys.readouterr().out
    assert "t_forms" in out and "dofs" in out  # every column
    assert (folder / "convergence_L2-all.pdf").exists() and "| level |" in (folder / "rates-all.md").read_text()
    assert cli.main(["report", str(folder), "--no-plots"]) == cli.EXIT_OK  # the study's own rates.tex
    own = (folder / "rates.tex").read_text()
    assert cli.main(["report", str(folder), "--no-plots", "--columns", "N,L2"]) == cli.EXIT_OK
    assert (folder / "rates-N-L2.md").read_text().splitlines()[1] == "| N | L² error | L² rate |"
    assert (folder / "rates.tex").read_text() == own  # beside the study's own table, never over it
    assert r"\label{tab:t-N-L2}" in (folder / "rates-N-L2.tex").read_text()
    assert cli.main(["report", str(folder), "--width", "2pt"]) == cli.EXIT_BAD_INPUT
    assert "--width: must be between 100pt and 2000pt" in capsys.readouterr().err


def cut_short(folder):
    text = (folder / "rates.csv").read_text()
    (folder / "rates.csv").write_text(text[:-30])
    (folder / "study.h5").unlink()


def no_table(folder):
    import h5py
    with h5py.File(folder / "study.h5", "a") as h5:
        del h5["table"]
    (folder / "rates.csv").unlink()


@pytest.mark.parametrize("damage, bad_file", [(cut_short, "rates.csv"), (no_table, "study.h5")])
def test_report_and_compare_on_damaged_results_exit_2_naming_it(make_config, capsys, damage, bad_file):
    good, bad = (make_config(study=name) for name in ("good", "bad"))
    for cfg in (good, bad):
        stop_after(cfg, 2)
    damage(bad.output_dir)
    assert cli.main(["report", str(bad.output_dir)]) == cli.EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{bad.output_dir / bad_file}: damaged" in err
    assert cli.main(["compare", str(good.output_dir), str(bad.output_dir)]) == cli.EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert err.startswith(f"signorini: error: {bad.output_dir}: ") and str(good.output_dir) not in err


@pytest.mark.parametrize("command", [["list"], ["report", "STUDY", "--no-plots"]])
def test_closed_stdout_ends_quietly(make_config, command):
    cfg = make_config()
    stop_after(cfg, 2)
    argv = [str(cfg.output_dir) if arg == "STUDY" else arg for arg in command]
    # `signorini ... | head -1`: the reader leaves after one line
    done = subprocess.run(f"{sys.executable} -m signorini_cli.app.cli {' '.join(argv)} | head -1", shell=True,
                          capture_output=True, text=True, timeout=120, executable="/bin/bash")
    assert done.stdout.count("\n") == 1 and done.stderr == ""
    # a reader gone before the first line (`| true` exits at once): every print meets a closed pipe
    status = subprocess.run(["bash", "-o", "pipefail", "-c", f"{sys.executable} -m signorini_cli.app.cli "
                             f"{' '.join(argv)} | true"], capture_output=True, timeout=120)
    assert status.returncode == 0 and status.stderr == b""


@pytest.mark.fast
def test_init_names_no_path_of_this_machine(capsys):
    assert cli.main(["init"]) == cli.EXIT_OK
    out = capsys.readouterr().out
    assert not re.search(r"(^|[\s'\"(:])/\w", out, re.M)  # no absolute path: the template is for any machine
    assert str(commands.SHIPPED_CONFIGS.parent) not in out and not re.search(r"issue\s*#?\d", out, re.I)


@pytest.mark.fast
def test_help_says_what_the_tool_is_in_one_line():
    text = cli.build_parser().format_help()
    description = text.split("\n\n")[1]
    assert "\n" not in description and "convergence studies" in description and "compliance" in description
