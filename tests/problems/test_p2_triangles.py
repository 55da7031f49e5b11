"""P2 on triangular Γ_C facets (3-D): the basis in the order of a facet's closure dofs, and the Γ_C integrals,
maximum and contact set of a quadratic trace exact against closed forms: w = r² − |x − c|² is positive on a
disk, where ∫[w]_+^β = π r^(2β+2)/(β+1), |{w > 0}| = π r² and max w = r²."""
import numpy as np
import pytest
from mpi4py import MPI

from dolfinx import fem
from signorini_cli.meshing import meshes
from signorini_cli.problems import contact, elasticity, element, kinked, measure

pytestmark = pytest.mark.fast
TOL = 1e-12  # the tanh-sinh rule on pieces between the cuts, where the integrands are smooth: round-off


def disk(r, c):
    """w = r² − |x − c|² (in the plane z = 0)."""
    return lambda x: r**2 - (x[..., 0] - c[0]) ** 2 - (x[..., 1] - c[1]) ** 2


def p2_facets(triangles, w):
    """(values (M, 6), points (M, 6, 3)) of w at the P2 nodes of triangles given by their vertices (M, 3, 2)."""
    vertices = np.concatenate((triangles, np.zeros(triangles.shape[:2] + (1,))), axis=2)
    points = np.einsum("qk,mkx->mqx", kinked.P2_NODES, vertices)
    return w(points), points


# the unit square as two triangles, in several vertex orders: the diagonal and the square's edges cut the disks
SQUARE = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], dtype=float)
ORDERS = [SQUARE, SQUARE[:, [1, 2, 0]], SQUARE[:, [2, 1, 0]]]
DISKS = [(0.3, (0.5, 0.5)), (0.2, (0.3, 0.6)), (0.45, (0.5, 0.52)), (0.1, (0.8, 0.15))]


@pytest.mark.parametrize("order", range(len(ORDERS)))
@pytest.mark.parametrize("r, c", DISKS)
def test_disk_integrals_exact(order, r, c):
    """∫[w]_+^β (β = 0 .. 3, the solve's and the measures' powers), its partition of unity through the basis
    (∫[w]_+^β φ_i summed over i, and φ_i φ_j over i, j), the contact set and the maximum, each to 1e-12."""
    values, points = p2_facets(ORDERS[order], disk(r, c))
    comm = MPI.COMM_SELF
    for beta in (0.0, 1.0, 1.5, 2.0, 3.0):
        expected = np.pi * r ** (2 * beta + 2) / (beta + 1)
        assert contact.positive_power(comm, values, points, beta, 2) == pytest.approx(expected, rel=TOL)
        assert contact.p2_integrals(points, values, beta, 1).sum() == pytest.approx(expected, rel=TOL)
        assert contact.p2_integrals(points, values, beta, 2).sum() == pytest.approx(expected, rel=TOL)
    assert measure.vertex_contact_measure(comm, values, points, 2) == pytest.approx(np.pi * r**2, rel=TOL)
    assert measure.vertex_penetration(comm, values, 2) == pytest.approx(r**2, rel=TOL)


def test_p2_basis_reproduces_quadratics():
    """Σ w(node_i) φ_i(λ) = w at random points of a triangle, for a quadratic w (the nodes of kinked.P2_NODES)."""
    rng = np.random.default_rng(0)
    triangle = np.array([[0.1, 0.2, 0.0], [0.9, 0.3, 0.0], [0.4, 0.8, 0.0]])
    def w(x):
        return 1 + 2 * x[..., 0] - x[..., 1] + 3 * x[..., 0] ** 2 - x[..., 0] * x[..., 1] + 0.5 * x[..., 1] ** 2
    lam = rng.dirichlet(np.ones(3), size=50)
    values = w(kinked.P2_NODES @ triangle)
    assert measure.p2_basis(lam) @ values == pytest.approx(w(lam @ triangle), rel=1e-14)


def test_triangle_max_against_a_dense_lattice():
    """The maximum of random quadratics on a triangle: at least every lattice value, and within the lattice's
    O(spacing²) of its largest (spacing 1/400)."""
    rng = np.random.default_rng(1)
    values = rng.normal(size=(200, 6))
    n = 400
    lam = np.array([(i, j, n - i - j) for i in range(n + 1) for j in range(n + 1 - i)]) / n
    sampled = (measure.p2_basis(lam) @ values.T).max(axis=0)
    found = measure.triangle_max(values)
    assert np.all(found >= sampled - 1e-14)
    assert np.all(found - sampled <= 40 / n**2)


def test_closure_dofs_put_edge_k_opposite_vertex_k(make_config):
    """contact_facet_dofs of a tetrahedral mesh's P2 space: dof 3 + k of a facet is the midpoint of the edge
    opposite its vertex k, the order p2_basis and kinked.P2_NODES assume."""
    cfg = make_config(dimension=3, mesh={"kind": "unit_cube", "refinements": [2]})
    domain = meshes.build(cfg.mesh, cfg.contact, 2, MPI.COMM_SELF)
    _, points = measure.contact_facet_dofs(element.space(domain.mesh, 2), domain.facet_tags, meshes.CONTACT)
    assert len(points)
    for k, (i, j) in enumerate(((1, 2), (0, 2), (0, 1))):
        assert np.allclose(points[:, 3 + k], (points[:, i] + points[:, j]) / 2, rtol=0, atol=1e-15)


ELASTIC_3D = {"dimension": 3, "mesh": {"kind": "unit_cube", "refinements": [2]}, "element": {"degree": 2},
              "problem": {"pde": "elasticity", "exact": ["0", "0", "0"]}}


@pytest.mark.parametrize("comm", [pytest.param(MPI.COMM_SELF, id="serial"),
                                  pytest.param(MPI.COMM_WORLD, id="world", marks=pytest.mark.mpi)])
def test_elastic_gamma_c_quantities_of_a_quadratic_field(make_config, comm):
    """u = (0, 0, −w) with w = r² − |(x, y) − (1/2, 1/2)|² on the bottom face z = 0 (n = (0, 0, −1), so
    w_h = u_h·n = w: P2 holds it exactly) of the 2 × 2 × 2 cube, the disk cut by the facets' edges and
    centred on a vertex: penetration r², contact set πr², (1/ε)∫[w_h]_+^α = πr^(2α+2)/(α+1)/ε, and against
    w_ex = 0 pos_gc^(α+1) = πr^(2α+4)/(α+2) and L2_gc² = r⁴ − r²/3 + 1/40 + 1/72 (the square's moments)."""
    cfg = make_config(**ELASTIC_3D)
    domain = meshes.build(cfg.mesh, cfg.contact, 2, comm)
    u_h = fem.Function(elasticity.space(cfg, domain.mesh))
    r, alpha, eps = 0.3, cfg.alpha, 0.01
    u_h.interpolate(lambda x: np.stack((0 * x[0], 0 * x[0], -(r**2 - (x[0] - 0.5) ** 2 - (x[1] - 0.5) ** 2))))
    term = elasticity.contact_term(cfg, domain, u_h, fem.Constant(domain.mesh, eps), measuring=True)
    values, points = term.values(u_h.x.array), term.points
    assert measure.vertex_penetration(comm, values, 2) == pytest.approx(r**2, rel=TOL)
    assert measure.vertex_contact_measure(comm, values, points, 2) == pytest.approx(np.pi * r**2, rel=TOL)
    force = contact.positive_power(comm, values, points, alpha, 2) / eps
    assert force == pytest.approx(np.pi * r ** (2 * alpha + 2) / (alpha + 1) / eps, rel=TOL)
    found = measure.contact_errors(comm, points[:, :3], values, lambda facets, x: 0 * x[..., 0], eps, alpha, 0.0)
    assert found["pos_gc"] ** (alpha + 1) == pytest.approx(np.pi * r ** (2 * alpha + 4) / (alpha + 2), rel=TOL)
    assert found["L2_gc"] ** 2 == pytest.approx(r**4 - r**2 / 3 + 1 / 40 + 1 / 72, rel=TOL)
