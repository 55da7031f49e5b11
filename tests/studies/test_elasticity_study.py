"""Elastic refinement studies through the problem registry: the rates of configs/elasticity on coarse levels,
the stiff case, the rigid-motion AMG, and 2 ranks equal to 1 rank."""
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from dolfinx import fem

from signorini_cli import config, studies
from signorini_cli.analysis import verdict
from signorini_cli.meshing import meshes
from signorini_cli.problems import elasticity
from signorini_cli.solve import transfer

CONFIGS = Path(__file__).resolve().parents[2] / "configs" / "elasticity"
MEASURED = ("L2", "H1", "L2_gc", "pos_gc", "energy_err", "penetration", "contact_measure", "contact_force")


def load(name, tmp_path, *overrides):
    return config.load(CONFIGS / name, [f"output.dir={tmp_path}", *overrides])


def rate(levels, norm):
    return np.log(levels[-1].errors[norm] / levels[-2].errors[norm]) / np.log(levels[-1].h / levels[-2].h)


@pytest.mark.slow
@pytest.mark.parametrize("alpha", ("15", "2", "3"))
def test_square_rates(tmp_path, alpha):
    """N = 8, 16, 32: observed H1 rates 0.99-1.00 and L2 rates 1.94-2.00 on the last pair (make elasticity,
    docs/elasticity.md); 0.05 and 0.1 are pre-asymptotic margins."""
    levels = studies.run_study(load(f"square-alpha{alpha}.yaml", tmp_path, "mesh.refinements=[8, 16, 32]"),
                               comm=MPI.COMM_SELF)
    assert all(lv.outcome.converged for lv in levels)
    assert rate(levels, "H1") >= 1.0 - 0.05
    assert rate(levels, "L2") >= 2.0 - 0.1


@pytest.mark.slow
def test_cube_rates(tmp_path):
    """N = 4, 8, 16 (alpha = 2): observed H1 0.96 and L2 1.77 on the last pair, still pre-asymptotic (1.91 and
    0.99 at N = 32, docs/elasticity.md): 0.1 and 0.3 are that margin."""
    levels = studies.run_study(load("cube-alpha2.yaml", tmp_path, "mesh.refinements=[4, 8, 16]"), comm=MPI.COMM_SELF)
    assert all(lv.outcome.converged for lv in levels)
    assert rate(levels, "H1") >= 1.0 - 0.1
    assert rate(levels, "L2") >= 2.0 - 0.3


def test_stiff_case_converges_every_level(tmp_path):
    """alpha = 2, eps = 1e-8: every level converges (the first by eps-continuation if Newton fails), at
    the rates of eps = h (make elasticity: H1 1.00, L2 1.96 from N = 16 to 32; margins as above)."""
    levels = studies.run_study(load("square-stiff.yaml", tmp_path, "mesh.refinements=[8, 16, 32]"), comm=MPI.COMM_SELF)
    assert all(lv.outcome.converged for lv in levels)
    assert rate(levels, "H1") >= 1.0 - 0.05
    assert rate(levels, "L2") >= 2.0 - 0.1


def test_verdict_not_covered(tmp_path):
    """The paper's estimates are for the scalar problem: no rate is claimed for elasticity."""
    cfg = load("square-alpha2.yaml", tmp_path, "mesh.refinements=[4, 8]")
    found = verdict.expected(cfg, "H1")
    assert found.rate is None and "scalar problem" in found.reason


def test_gamg_with_rigid_motions_takes_few_iterations(tmp_path):
    """CG + GAMG with the rigid motions as near-nullspace: at N = 64 each Newton step takes < 30 CG
    iterations (observed 9-12 per step; plain-Laplacian AMG coarsening of elasticity typically needs
    several times more)."""
    cfg = load("square-alpha2.yaml", tmp_path, "mesh.refinements=[64]", "solver.linear=iterative")
    (level,) = studies.run_study(cfg, comm=MPI.COMM_SELF)
    assert level.outcome.converged and not level.outcome.linear_fallback
    assert level.outcome.linear_its < 30 * level.outcome.newton_its


@pytest.mark.parametrize("dim", (2, 3, pytest.param(2, marks=pytest.mark.mpi, id="2-mpi"),
                                 pytest.param(3, marks=pytest.mark.mpi, id="3-mpi")))
def test_nested_iteration_moves_vector_fields_exactly(tmp_path, dim):
    """transfer moves a vector P1 function component by component: exact on nested meshes (u affine)."""
    cfg = load("square-alpha2.yaml" if dim == 2 else "cube-alpha2.yaml", tmp_path)
    spaces = []
    for n in (2, 4):
        domain = meshes.build(cfg.mesh, cfg.contact, n, MPI.COMM_WORLD)
        spaces.append(elasticity.space(cfg, domain.mesh))
    affine = lambda x: np.stack([1 + 2 * x[0] - x[1], 3 * x[1] + x[dim - 1], x[0] - 4 * x[2]][:dim])  # noqa: E731
    coarse, fine = fem.Function(spaces[0]), fem.Function(spaces[1])
    coarse.interpolate(affine)
    fine.interpolate(affine)
    moved = transfer.transfer(coarse, spaces[1])
    local = np.abs(moved.x.array - fine.x.array).max(initial=0.0)
    assert MPI.COMM_WORLD.allreduce(local, op=MPI.MAX) <= 1e-14  # round-off of values of size ~5


def run_both(tmp_path, name, refinements):
    """The study on COMM_WORLD and on COMM_SELF (each rank alone): its measured columns, both ways."""
    out = []
    for comm in (MPI.COMM_WORLD, MPI.COMM_SELF):
        where = tmp_path / f"{comm.size}-{MPI.COMM_WORLD.rank}"
        levels = studies.run_study(load(name, where, f"mesh.refinements={refinements}"), comm=comm)
        out.append(np.array([[{**lv.errors, **lv.extra}[k] for k in MEASURED] for lv in levels]))
    return out


@pytest.mark.mpi
@pytest.mark.parametrize("name, refinements", [("square-alpha2.yaml", [8, 16]), ("cube-alpha3.yaml", [4, 8]),
                                               ("square-stiff.yaml", [8, 16])])
def test_two_ranks_equal_serial(tmp_path, name, refinements):
    """2 ranks give the serial numbers to 1e-8 relative (the issue's bar; observed ~1e-14: sums in
    another order)."""
    assert MPI.COMM_WORLD.size == 2
    parallel, serial = run_both(tmp_path, name, refinements)
    difference = np.max(np.abs(parallel - serial) / np.abs(serial))  # every entry is nonzero here
    assert MPI.COMM_WORLD.allreduce(difference, op=MPI.MAX) <= 1e-8
