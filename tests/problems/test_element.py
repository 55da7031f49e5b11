"""The element seam: spaces by degree, the quadrature degrees that depend on it, and the Γ_C measures of
P2 (a quadratic on each Γ_C segment: its maximum and positive part in closed form); serial and on 2 ranks."""
import numpy as np
import pytest
from mpi4py import MPI

from dolfinx import fem
from signorini_cli import config
from signorini_cli.meshing import meshes
from signorini_cli.meshing.meshes import CONTACT
from signorini_cli.problems import element, measure

WORLD = [pytest.param(MPI.COMM_SELF, id="serial"), pytest.param(MPI.COMM_WORLD, id="world", marks=pytest.mark.mpi)]


@pytest.mark.fast
@pytest.mark.parametrize("degree, shape, dofs", [(1, None, 25), (2, None, 81), (2, (2,), 162)])
def test_space_by_degree(degree, shape, dofs):
    domain = meshes.build(config.Mesh("unit_square"), "bottom", 4, MPI.COMM_SELF)
    V = element.space(domain.mesh, degree, shape)
    assert element.degree_of(V) == degree
    assert V.dofmap.index_map.size_global * V.dofmap.index_map_bs == dofs  # (2N+1)^2 nodes for P2


@pytest.mark.fast
@pytest.mark.parametrize("values, top, fraction", [
    ([0.0, 0.0, 0.25], 0.25, 1.0),        # t(1 - t): positive inside, max 1/4 at t = 1/2
    ([1.0, -1.0, 0.0], 1.0, 0.5),         # linear: the zero at t = 1/2
    ([-1.0, -1.0, -0.5], 0.0, 0.0),       # concave and negative: [max]_+ = 0, nowhere positive
    ([0.04, -0.06, 0.0275], None, None),  # two zeros, a maximum inside: against sampling only
])
def test_quadratic_max_and_positive_fraction(values, top, fraction):
    values = np.array([values])
    t = np.linspace(0, 1, 200001)
    a, B, C = measure.quadratic(values)
    p = a[0] + B[0] * t + C[0] * t**2
    assert np.allclose(p[[0, -1, 100000]], values[0][[0, 1, 2]], atol=1e-15)
    # sampled at spacing 5e-6, the maximum is off by at most |p''| (5e-6)^2 / 8 and the measure by 1e-5
    assert measure.quadratic_max(values)[0] == pytest.approx(p.max(), abs=1e-10)
    assert measure.quadratic_positive_fraction(values)[0] == pytest.approx(np.mean(p > 0), abs=1e-5)
    if top is not None:
        assert max(measure.quadratic_max(values)[0], 0.0) == pytest.approx(top, rel=1e-14)
        assert measure.quadratic_positive_fraction(values)[0] == pytest.approx(fraction, rel=1e-14)


@pytest.mark.parametrize("comm", WORLD)
def test_p2_penetration_and_contact_measure_exact(comm):
    """u = 0.04 − (x − 0.45)² on Γ_C (y = 0) is in P2: max 0.04 at x = 0.45, inside a facet of N = 4 (a
    nodal maximum would give 0.0375), and u > 0 on (0.25, 0.65), of measure 0.4."""
    domain = meshes.build(config.Mesh("unit_square"), "bottom", 4, comm)
    u = fem.Function(element.space(domain.mesh, 2))
    u.interpolate(lambda x: 0.04 - (x[0] - 0.45) ** 2 + 0.3 * x[1])
    dofs, points = measure.contact_facet_dofs(u.function_space, domain.facet_tags, CONTACT)
    assert measure.penetration(u, dofs) == pytest.approx(0.04, rel=1e-13)  # round-off of the P2 values
    assert measure.contact_measure(u, dofs, points) == pytest.approx(0.4, rel=1e-13)
    # the facet dofs: the two vertices, then the edge's midpoint
    assert np.allclose(points[:, 2], (points[:, 0] + points[:, 1]) / 2)


@pytest.mark.fast
def test_error_quadrature_rises_with_the_degree():
    for h in (0.1, 0.01):
        assert element.error_degree(2, h, 2) == element.error_degree(1, h, 2) + 2
    assert element.product_degree(2) == 4
