"""rates.csv and study.h5: the leading columns, written after every level, readable when cut short, self-describing."""
import csv
import re

import h5py
import pytest
import yaml
from mpi4py import MPI

from signorini_cli import studies
from signorini_cli.record import h5 as record_h5, results


def test_half_finished_study_is_readable(partial_study):
    cfg = partial_study
    with open(cfg.output_dir / "rates.csv") as f:
        rows = list(csv.DictReader(f))
    assert [row["N"] for row in rows] == ["4", "8"]
    assert list(rows[0])[:len(studies.level.LEADING_COLUMNS)] == list(studies.level.LEADING_COLUMNS)
    assert rows[0]["rate_L2"] == "" and float(rows[1]["rate_L2"]) > 1
    assert rows[1]["converged"] == "true"
    with h5py.File(cfg.output_dir / "study.h5") as h5:
        assert h5.attrs["levels_done"] == 2 and h5.attrs["mpi_size"] >= 1
        assert "alpha: 2.0" in h5.attrs["config"] and h5.attrs["version_dolfinx"] == "0.5.2"
        assert sorted(h5) == ["level_00", "level_01", "pressure", "table", "verification", "work_precision"]
        assert h5["table/L2"][1] == pytest.approx(float(rows[1]["L2"]), rel=1e-15)
        assert h5["level_01"].attrs["N"] == 8 and len(h5["level_01/residuals"]) >= 2
    assert not list(cfg.output_dir.glob(".*.tmp*"))  # atomic replace left no temporary files


def test_h5_records_resolved_config_column_order_and_revision(make_config):
    cfg = make_config(mesh={"refinements": [4]})
    rows = results.write(studies.study_of(cfg, studies.run_study(cfg, comm=MPI.COMM_SELF)), comm=MPI.COMM_SELF)
    with h5py.File(cfg.output_dir / "study.h5") as h5:
        assert list(h5["table"].attrs["columns"]) == list(rows[0])
        assert yaml.safe_load(h5.attrs["config_resolved"])["output"]["digits"] == 3  # defaults filled in
        assert h5.attrs["time_total_s"] == pytest.approx(rows[0]["time_s"])
        if results.git_revision():  # the tests run from a git checkout; an unpacked copy has none
            assert re.fullmatch(r"[0-9a-f]{40}(\+dirty)?", h5.attrs["git_revision"])
        else:
            assert "git_revision" not in h5.attrs


def test_status_and_config_hash_recorded(make_config):
    from signorini_cli import config
    cfg = make_config()
    results.write(studies.study_of(cfg, studies.run_study(cfg)), status="complete")
    assert (cfg.output_dir / results.STATUS_FILE).read_text() == "complete\n"
    with h5py.File(cfg.output_dir / "study.h5") as h5:
        assert h5.attrs["status"] == "complete" and h5.attrs["config_hash"] == config.fingerprint(cfg)
        assert list(h5["table"].attrs["columns"])[:len(studies.level.LEADING_COLUMNS)] == list(studies.level.LEADING_COLUMNS)


def test_level_group_keeps_every_solve(make_config):
    # max_it = 4 is one short at N = 16 from u = 0 (5 needed): auto's attempt fails; continuation then
    # solves at eps_0 = 1 (4 iterations), 0.1 (2: easy, so the ratio squares to 0.01) and eps = h (2)
    cfg = make_config(mesh={"refinements": [16]}, solver={"max_it": 4})
    results.write(studies.study_of(cfg, studies.run_study(cfg)))
    with h5py.File(cfg.output_dir / "study.h5") as h5:
        level = h5["level_00"]
        eps = level.attrs["epsilon"]
        assert list(level["solve_eps"]) == pytest.approx([eps, 1.0, 0.1, eps])
        reasons = [r.decode() for r in level["solve_reason"]]
        assert reasons[0] == "DIVERGED_MAX_IT" and all(r.startswith("CONVERGED") for r in reasons[1:])
        its = list(level["solve_newton_its"])
        assert len(level["residuals"]) == sum(n + 1 for n in its)  # each history: its + 1 norms
        assert level.attrs["newton_its"] == sum(its) and level.attrs["continuation_steps"] == 3


def test_h5_describes_itself(partial_study):
    """Counts and flags are integers, and every dataset and attribute-bearing group says what it holds and
    in which units: h5py (or h5dump) alone explains the file."""
    found = []
    with h5py.File(partial_study.output_dir / "study.h5") as h5:
        for column in ("level", "N", "dofs", "newton_its", "linear_its"):
            assert h5["table"][column].dtype.kind == "i", column
        assert h5["table/converged"].dtype == bool  # HDF5 enum FALSE = 0, TRUE = 1 on int8
        assert h5["level_00"].attrs["N"].dtype.kind == "i" and h5["level_00/solve_newton_its"].dtype.kind == "i"
        h5.visititems(lambda name, node: found.append((name, node)))
        for name, node in [("/", h5)] + found:  # every group and dataset
            assert node.attrs["description"] and "units" in node.attrs, name
            assert "\n" not in node.attrs["description"], name  # one line
    described = {name.rsplit("/", 1)[-1] for name, node in found
                 if isinstance(node, h5py.Dataset) and not name.startswith("level_")}
    assert not [c for c in described if record_h5.column_info(c) == ("", c.replace("_", " "))]


def test_every_table_reads_back_as_written(make_config):
    cfg = make_config(mesh={"refinements": [4, 8]})
    levels = studies.run_study(cfg, comm=MPI.COMM_SELF)
    named = studies.of(cfg.study_type).tables(cfg, levels)
    results.write_files(studies.study_of(cfg, levels), 1)
    study = results.load(cfg.output_dir)
    assert list(study.tables) == list(named) == ["rates", "pressure", "work_precision"]
    for name, rows in named.items():
        for read, written in zip(study.tables[name], rows):
            assert read.keys() == written.keys()
            for column, value in written.items():
                if isinstance(value, float):
                    assert read[column] == pytest.approx(value, rel=1e-15, abs=0)  # float64 both ways
                else:
                    assert read[column] == value and type(read[column]) is type(value), column


def opens_h5(path):
    """Whether the module's code (not its text: docs examples) calls h5py.File."""
    import ast
    return any(isinstance(node, ast.Attribute) and node.attr == "File" and getattr(node.value, "id", "") == "h5py"
               for node in ast.walk(ast.parse(path.read_text())))


def test_one_module_opens_study_h5():
    """h5py.File is opened in record/h5.py alone: the package and the page scripts read through it."""
    from pathlib import Path
    root = Path(results.__file__).resolve().parents[2]
    sources = list((root / "signorini_cli").rglob("*.py")) + list((root / "scripts").glob("*.py"))
    opening = sorted(str(p.relative_to(root)) for p in sources if opens_h5(p))
    assert opening == ["signorini_cli/record/h5.py"]
