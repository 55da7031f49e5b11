"""rates.csv and study.h5: the leading columns, written after every level, readable when cut short."""
import csv
import re

import h5py
import pytest
import yaml
from mpi4py import MPI

from signorini_cli import studies
from signorini_cli.record import results


def test_half_finished_study_is_readable(partial_study):
    cfg = partial_study
    with open(cfg.output_dir / "rates.csv") as f:
        rows = list(csv.DictReader(f))
    assert [row["N"] for row in rows] == ["4", "8"]
    assert list(rows[0])[:len(results.SPEC_COLUMNS)] == list(results.SPEC_COLUMNS)
    assert rows[0]["rate_L2"] == "" and float(rows[1]["rate_L2"]) > 1
    assert rows[1]["converged"] == "true"
    with h5py.File(cfg.output_dir / "study.h5") as h5:
        assert h5.attrs["levels_done"] == 2 and h5.attrs["mpi_size"] >= 1
        assert "alpha: 2.0" in h5.attrs["config"] and h5.attrs["version_dolfinx"] == "0.5.2"
        assert sorted(h5) == ["level_00", "level_01", "table", "verification"]
        assert h5["table/L2"][1] == pytest.approx(float(rows[1]["L2"]), rel=1e-15)
        assert h5["level_01"].attrs["N"] == 8 and len(h5["level_01/residuals"]) >= 2
    assert not list(cfg.output_dir.glob(".*.tmp*"))  # atomic replace left no temporary files


def test_h5_records_resolved_config_column_order_and_revision(make_config):
    cfg = make_config(mesh={"refinements": [4]})
    rows = results.write(cfg, studies.run_study(cfg, comm=MPI.COMM_SELF), comm=MPI.COMM_SELF)
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
    results.write(cfg, studies.run_study(cfg), status="complete")
    assert (cfg.output_dir / results.STATUS_FILE).read_text() == "complete\n"
    with h5py.File(cfg.output_dir / "study.h5") as h5:
        assert h5.attrs["status"] == "complete" and h5.attrs["config_hash"] == config.fingerprint(cfg)
        assert list(h5["table"].attrs["columns"])[:len(results.SPEC_COLUMNS)] == list(results.SPEC_COLUMNS)


def test_level_group_keeps_every_solve(make_config):
    # max_it = 4 is one short at N = 16 from u = 0 (5 needed): auto's attempt fails; continuation then
    # solves at eps_0 = 1 (4 iterations), 0.1 (2: easy, so the ratio squares to 0.01) and eps = h (2)
    cfg = make_config(mesh={"refinements": [16]}, solver={"max_it": 4})
    results.write(cfg, studies.run_study(cfg))
    with h5py.File(cfg.output_dir / "study.h5") as h5:
        level = h5["level_00"]
        eps = level.attrs["epsilon"]
        assert list(level["solve_eps"]) == pytest.approx([eps, 1.0, 0.1, eps])
        reasons = [r.decode() for r in level["solve_reason"]]
        assert reasons[0] == "DIVERGED_MAX_IT" and all(r.startswith("CONVERGED") for r in reasons[1:])
        its = list(level["solve_newton_its"])
        assert len(level["residuals"]) == sum(n + 1 for n in its)  # each history: its + 1 norms
        assert level.attrs["newton_its"] == sum(its) and level.attrs["continuation_steps"] == 3
