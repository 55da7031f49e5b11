"""Every shipped config is valid and runs on its two coarsest levels (examples are tests)."""
from pathlib import Path

import pytest
from mpi4py import MPI

from signorini_cli import config, study

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = sorted(ROOT.glob("configs/**/*.yaml"))
parametrize_configs = pytest.mark.parametrize("path", CONFIGS, ids=[str(p.relative_to(ROOT / "configs")) for p in CONFIGS])


def coarse(path, tmp_path):
    cfg = config.load(path)
    return config.loads(cfg.text, [f"mesh.{cfg.mesh.level_key}={list(cfg.mesh.levels[:2])}",
                                   f"output.dir={tmp_path}"])


@parametrize_configs
def test_config_header_states_prediction(path):
    header = [line for line in path.read_text().splitlines() if line.startswith("#")]
    assert any("Paper" in line or "paper" in line for line in header)  # says what the paper predicts
    assert config.load(path).description


@parametrize_configs
def test_config_runs_coarse(path, tmp_path):
    levels = study.run_study(coarse(path, tmp_path), comm=MPI.COMM_SELF)
    assert all(lv.outcome.converged for lv in levels)


@pytest.mark.mpi
@parametrize_configs
def test_config_runs_coarse_two_ranks(path, tmp_path):
    assert MPI.COMM_WORLD.size == 2
    levels = study.run_study(coarse(path, tmp_path))
    assert MPI.COMM_WORLD.allreduce(all(lv.outcome.converged for lv in levels), op=MPI.LAND)
