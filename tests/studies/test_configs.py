"""Every shipped config is valid and runs on its two coarsest levels (examples are tests)."""
from pathlib import Path

import pytest
from mpi4py import MPI

from signorini_cli import config, studies
from signorini_cli.analysis import verdict

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = sorted(ROOT.glob("configs/**/*.yaml"))
parametrize_configs = pytest.mark.parametrize("path", CONFIGS, ids=[str(p.relative_to(ROOT / "configs")) for p in CONFIGS])


def coarse(path, tmp_path):
    """The config on its two coarsest levels; a map's first point (the map validated all of them)."""
    cfg = config.load(path)
    cfg = config.load(path, [f"mesh.{cfg.mesh.level_key}={list(cfg.mesh.levels[:2])}", f"output.dir={tmp_path}"])
    return cfg.map.studies[0] if cfg.study_type == "map" else cfg


@parametrize_configs
def test_config_header_cites_the_proven_rates(path):
    """The header names the paper's result behind every rate the verdict checks for H1 and L2 (as
    verdict.expected finds it for the scene: none for the elastic problem), so header and verdict cannot
    drift apart."""
    cfg = config.load(path)
    assert cfg.description
    if (cfg.study_type != "refinement" or cfg.problem.exact is None or not cfg.verification.regular
            or cfg.positive_part.kind != "exact"):  # the paper says nothing of a smoothed positive part
        return
    header = " ".join(line for line in path.read_text().splitlines() if line.startswith("#"))
    for norm in ("H1", "L2"):
        found = verdict.expected(cfg, norm)
        if found.rate is not None:
            cited = " ".join(found.reference.split()[:2])  # "Cor. 3.2 i" is cited as "Cor. 3.2"
            assert cited in header, f"{norm}: {found.reference} (rate {found.rate:g}) not cited"


@parametrize_configs
def test_config_runs_coarse(path, tmp_path):
    levels = studies.run_study(coarse(path, tmp_path), comm=MPI.COMM_SELF)
    assert all(lv.outcome.converged for lv in levels)


@pytest.mark.mpi
@parametrize_configs
def test_config_runs_coarse_two_ranks(path, tmp_path):
    assert MPI.COMM_WORLD.size == 2
    levels = studies.run_study(coarse(path, tmp_path))
    assert MPI.COMM_WORLD.allreduce(all(lv.outcome.converged for lv in levels), op=MPI.LAND)
