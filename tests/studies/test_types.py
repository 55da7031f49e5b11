"""The study-type seam: every type runs, records and reports itself; report and compare work on each."""
import ast
from pathlib import Path

import pytest
import yaml

from signorini_cli import studies
from signorini_cli.app import cli
from signorini_cli.record import results
from conftest import BASE, U_SIGNORINI, merge

PACKAGE = Path(studies.__file__).resolve().parents[1]
LIMIT = {"alpha": None, "epsilon": None, "problem": {"exact": U_SIGNORINI, "exact_solves": "signorini"}}
# coarse: each runs in a few seconds; what matters is what is written, not the numbers
TYPES = {
    "signorini": dict(LIMIT, study_type="signorini"),
    "epsilon_sweep": dict(LIMIT, study_type="epsilon_sweep", mesh={"refinements": [4]},
                          limit={"alpha": [2], "epsilon": [1e-1, 1e-2]}),
    "total_error": dict(LIMIT, study_type="total_error", limit={"alpha": [2], "exponent": [1]}),
}
# what `report` writes of each type: its tables as Markdown and LaTeX, and its figures
REPORTED = {
    "signorini": ["rates.md", "rates.tex", "convergence.pdf", "newton.pdf"],
    "epsilon_sweep": ["sweep.md", "sweep.tex", "fitted.md", "fitted.tex", "reference.md", "reference.tex",
                      "model_error.png", "model_error.pdf"],
    "total_error": ["total.md", "total.tex", "alpha2-p1/rates.tex", "signorini/rates.tex",
                    "alpha2-p1/convergence.pdf", "compare_convergence.pdf"],
}


def names_a_type(side):
    """Whether one side of a comparison is a study type: x.study_type, study_type or get("study_type")."""
    if isinstance(side, ast.Attribute) and side.attr == "study_type" or getattr(side, "id", "") == "study_type":
        return True
    return isinstance(side, ast.Call) and any(getattr(a, "value", None) == "study_type" for a in side.args)


def comparisons(path):
    """(line, text) of every comparison in a module with a study type on one side."""
    return [(node.lineno, ast.unparse(node)) for node in ast.walk(ast.parse(path.read_text()))
            if isinstance(node, ast.Compare) and any(map(names_a_type, [node.left] + node.comparators))]


@pytest.mark.fast
def test_study_type_compared_only_in_studies_and_config():
    """A study type is one module of studies/ (and its config section): nothing else branches on it."""
    outside = {str(p.relative_to(PACKAGE)): comparisons(p) for p in PACKAGE.rglob("*.py")
               if p.parent.name not in ("studies", "config")}
    assert {path: found for path, found in outside.items() if found} == {}


@pytest.mark.fast
def test_every_type_is_one_module_with_the_whole_seam():
    for name, module in studies.STUDY_TYPES.items():
        assert module.NAME == name and module.UNIT in ("levels", "solves", "points") and callable(module.run)
        if module.POINTS:  # a map: its points are studies of their own, recorded by app/maps
            continue
        for function in ("tables", "summary", "levels_of", "parts", "reported", "compared", "title"):
            assert callable(getattr(module, function)), (name, function)


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """One coarse finished study of every type: study type -> its folder."""
    root = tmp_path_factory.mktemp("types")
    folders = {}
    for kind, changes in TYPES.items():
        path = root / f"{kind}.yaml"
        raw = merge(BASE, dict(changes, study=kind, output={"dir": str(root / "out"), "plots": False}))
        path.write_text(yaml.safe_dump(raw))
        assert cli.main(["run", str(path), "--quiet"]) == cli.EXIT_OK
        folders[kind] = root / "out" / kind
    return folders


@pytest.mark.parametrize("kind", TYPES)
def test_report_writes_every_table_and_figure_of_its_type(finished, kind, capsys):
    folder = finished[kind]
    assert not (folder / REPORTED[kind][-1]).exists()  # output.plots: false: no figure yet
    for name in REPORTED[kind]:
        (folder / name).unlink(missing_ok=True)  # the tables the run wrote: report writes them again
    assert cli.main(["report", str(folder)]) == cli.EXIT_OK
    out, err = capsys.readouterr()
    assert err == "" and out.startswith(f"study {kind}: ")
    for name in REPORTED[kind]:
        assert (folder / name).stat().st_size > 0, name
    for name in REPORTED[kind]:  # named as they lie below the folder; a sub-study's folder with its count
        assert name in out or f"{name.split('/')[0]}/ (" in out, name


def test_report_reads_each_type_from_its_record(finished):
    """study.h5 alone gives back the type and every table it reports (its main table first)."""
    for kind, folder in finished.items():
        study = results.load(folder)
        shown, _ = studies.of(kind).reported(None, study.tables)
        assert study.study_type == kind and study.rows == next(iter(study.tables.values()))
        assert shown[0].rows == study.rows


def test_compare_overlays_every_type(finished, tmp_path, capsys):
    """compare on a signorini, an ε-sweep and a total-error study: each type's rate tables, one line each."""
    folders = [str(finished[kind]) for kind in TYPES]
    assert cli.main(["compare", *folders, "--output", str(tmp_path / "c")]) == cli.EXIT_OK
    table = capsys.readouterr().out.splitlines()
    labels = ["signorini", "epsilon_sweep reference", "total_error alpha2-p1", "total_error signorini"]
    for label in labels:
        assert any(line.strip().startswith(label) for line in table), label
    assert (tmp_path / "c" / "compare_convergence.pdf").exists()


def test_report_names_a_missing_table(finished, tmp_path, capsys):
    """A record without a table its type reports is damaged: one line, exit 2, no traceback."""
    import shutil
    import h5py
    folder = tmp_path / "sweep"
    shutil.copytree(finished["epsilon_sweep"], folder)
    with h5py.File(folder / "study.h5", "a") as h5:
        del h5["fitted"]
    assert cli.main(["report", str(folder)]) == cli.EXIT_BAD_INPUT
    assert capsys.readouterr().err == (f"signorini: error: {folder}: {folder}/study.h5: damaged, no table "
                                       "'fitted' (study_type epsilon_sweep)\n")
