"""A P2 refinement study (element.degree 2) on coarse levels: its rates are P2's interpolation orders, and
2 ranks give the serial errors; nested iteration moves P2 solutions exactly between nested meshes."""
import numpy as np
import pytest
from mpi4py import MPI

from dolfinx import fem
from signorini_cli import studies
from signorini_cli.meshing import meshes
from signorini_cli.problems import element
from signorini_cli.solve.transfer import transfer

P2 = {"element": {"degree": 2}, "mesh": {"refinements": [8, 16, 32]}}


def errors(levels):
    return [dict(lv.errors) for lv in levels]


def test_p2_rates(make_config):
    """L2 O(h^3) and H1 O(h^2), the interpolation orders of P2, within 0.1 (the verdicts' default tolerance;
    measured 2.97, 2.99 and 1.96, 1.98 on these levels)."""
    levels = studies.run_study(make_config(**P2), comm=MPI.COMM_SELF)
    assert all(lv.outcome.converged for lv in levels)
    h = np.array([lv.h for lv in levels])
    for norm, order in (("L2", 3), ("H1", 2)):
        e = np.array([lv.errors[norm] for lv in levels])
        assert np.log(e[1:] / e[:-1]) / np.log(h[1:] / h[:-1]) == pytest.approx([order] * 2, abs=0.1)
    assert {lv.extra["contact_quadrature"] for lv in levels} == {"exact"}  # the default rule, recorded


@pytest.mark.mpi
def test_p2_same_errors_on_two_ranks(make_config):
    """Every error of the P2 study on 2 ranks is the serial one to 1e-8 relative: the contact rule, the error
    quadrature and Newton (converged to |F| < 1e-10 or so) are partition independent up to that."""
    cfg = make_config(**P2)
    serial, parallel = (errors(studies.run_study(cfg, comm=comm)) for comm in (MPI.COMM_SELF, MPI.COMM_WORLD))
    for one, two in zip(serial, parallel):
        assert one.keys() == two.keys()
        for name in one:
            assert two[name] == pytest.approx(one[name], rel=1e-8), name


@pytest.mark.parametrize("comm", [pytest.param(MPI.COMM_SELF, id="serial"),
                                  pytest.param(MPI.COMM_WORLD, id="world", marks=pytest.mark.mpi)])
def test_p2_transfer_exact_on_nested_meshes(make_config, comm):
    """A quadratic is in P2 on both meshes: moved from N = 4 to N = 8 it is the same function (round-off)."""
    cfg = make_config()
    coarse, fine = (element.space(meshes.build(cfg.mesh, cfg.contact, n, comm).mesh, 2) for n in (4, 8))
    u, expected = fem.Function(coarse), fem.Function(fine)
    quadratic = lambda x: 1 + x[0] - 2 * x[1] + 3 * x[0] * x[1] - x[1] ** 2  # noqa: E731
    u.interpolate(quadratic)
    expected.interpolate(quadratic)
    assert np.allclose(transfer(u, fine).x.array, expected.x.array, rtol=0, atol=1e-13)
