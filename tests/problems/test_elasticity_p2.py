"""P2 linear elasticity (element.degree 2): P2's orders on a smooth 2-D manufactured case with ε = h, and the
Γ_C quantities of a solved level exact against a brute-force integral of its own u_h, evaluated by dolfinx
along Γ_C; 2 ranks give the serial study in 2-D and 3-D (3-D Γ_C rules: tests/problems/test_p2_triangles.py)."""
import numpy as np
import pytest
import ufl
from mpi4py import MPI
from scipy import optimize

from conftest import merge

from dolfinx import geometry
from signorini_cli import studies
from signorini_cli.problems import elasticity, measure
from signorini_cli.studies import refinement, verification

QUANTITIES = ["pos_gc", "energy_err", "penetration", "contact_measure", "contact_force"]
# u·n = −u_y = −0.1 cos(2πx) on y = 0: contact for 1/4 < x < 3/4 (docs/elasticity.md's 2-D case)
P2_ELASTIC = {"element": {"degree": 2}, "mesh": {"refinements": [4, 8, 16]},
              "problem": {"pde": "elasticity", "exact": ["0.1*sin(pi*x)*y", "0.1*cos(2*pi*x)*(1 - y)**2"]},
              "material": {"E": 1.0, "nu": 0.3}, "verification": {"measures": QUANTITIES}}
STIFF = {"epsilon": {"law": "constant", "theta": 1e-8}, "solver": {"strategy": "auto"}}
# an affine initial gap g0 and a contact zone whose edges lie inside facets: w = −u_y − g0 on y = 0
SHIFTED = {"problem": {"exact": ["0.1*sin(pi*x)*y", "(0.1*cos(2*pi*(x - 0.3)) + 0.02*x)*(1 - y)**2"],
                       "gap": "0.01 - 0.05*x"}}


def test_p2_elastic_rates(make_config):
    """L2 O(h^3) and H1 O(h^2), P2's interpolation orders, within 0.1 on N = 4, 8, 16 (measured 3.00, 3.00
    and 1.93, 1.97): the penalty with ε = h keeps the element's orders, as for the scalar problem."""
    levels = studies.run_study(make_config(**P2_ELASTIC), comm=MPI.COMM_SELF)
    assert all(lv.outcome.converged for lv in levels)
    h = np.array([lv.h for lv in levels])
    for norm, order in (("L2", 3), ("H1", 2)):
        e = np.array([lv.errors[norm] for lv in levels])
        assert np.log(e[1:] / e[:-1]) / np.log(h[1:] / h[:-1]) == pytest.approx([order] * 2, abs=0.1)
    assert {lv.extra["contact_quadrature"] for lv in levels} == {"exact"}


def on_bottom(u_h):
    """w_h(x) = u_h·n − g0 = −u_y(x, 0) − g0 evaluated by dolfinx at points of y = 0 (g0 added by the caller)."""
    msh = u_h.function_space.mesh
    tree = geometry.BoundingBoxTree(msh, msh.topology.dim)

    def w_h(x):
        points = np.zeros((np.size(x), 3))
        points[:, 0] = x
        cells = geometry.compute_colliding_cells(msh, geometry.compute_collisions(tree, points), points)
        cell = np.array([cells.links(i)[0] for i in range(len(points))], dtype=np.int32)
        return -u_h.eval(points, cell).reshape(len(points), -1)[:, 1]
    return w_h


def zeros_of(f, grid):
    """The zeros of f by Brent's method in each cell of the grid where it changes sign."""
    values = f(grid)
    change = np.flatnonzero(np.sign(values[:-1]) != np.sign(values[1:]))
    return np.array([optimize.brentq(lambda t: f(np.array([t]))[0], grid[i], grid[i + 1], xtol=1e-15, rtol=1e-15)
                     for i in change])


def brute_force(w_h, w, n, alpha, eps, per_facet=4000):
    """Γ_C quantities of w_h on [0, 1] (n facets) against w: the zeros of w_h, w and w − w_h (zeros_of on a
    dense sample), the contact set's length from them, and a composite 2-point Gauss-Legendre rule with
    per_facet points on each piece between vertices and zeros, where the integrands are smooth, for
    ∫|[w]_+ − [w_h]_+|^(α+1) and (1/ε)∫[w_h]_+^α."""
    grid = np.linspace(0.0, 1.0, n * per_facet + 1)
    values = w_h(grid)
    kinks = [w_h, w, lambda t: w(t) - w_h(t)]
    zeros = [zeros_of(k, grid) for k in kinks]
    breaks = np.unique(np.concatenate([np.linspace(0.0, 1.0, n + 1)] + zeros))
    measure_ = sum(b - a for a, b in zip(breaks[:-1], breaks[1:]) if w_h(np.array([(a + b) / 2]))[0] > 0)
    halves = per_facet // 2
    s = ((np.arange(halves)[:, None] + 0.5 + np.array([-0.5, 0.5]) / np.sqrt(3)) / halves).ravel()
    t = np.concatenate([a + (b - a) * s for a, b in zip(breaks[:-1], breaks[1:])])
    width = np.repeat(np.diff(breaks), s.size) / s.size
    wt, wh = w(t), w_h(t)
    power = np.sum(width * np.abs(np.maximum(wt, 0) - np.maximum(wh, 0)) ** (alpha + 1))
    force = np.sum(width * np.maximum(wh, 0) ** alpha) / eps
    top = int(np.argmax(values))
    around = (grid[max(top - 1, 0)], grid[min(top + 1, grid.size - 1)])
    refined = optimize.minimize_scalar(lambda t: -w_h(np.array([t]))[0], bounds=around, method="bounded",
                                       options={"xatol": 1e-15})
    peak = max(values.max(), -refined.fun)  # the grid holds the vertices, where w_h may peak with a kink
    return {"pos_power": power, "contact_force": force, "contact_measure": measure_, "penetration": peak}


def w_exact(changes):
    """w = u_ex·n − g0 on y = 0 (n = (0, −1)) of each case below, and its g0, in numpy."""
    if changes is SHIFTED:
        return lambda x: -0.1 * np.cos(2 * np.pi * (x - 0.3)) - 0.02 * x - (0.01 - 0.05 * x), lambda x: 0.01 - 0.05 * x
    return lambda x: -0.1 * np.cos(2 * np.pi * x), lambda x: 0 * x


@pytest.mark.parametrize("changes", [pytest.param({}, id="eps-h"), pytest.param(STIFF, id="eps-1e-8"),
                                     pytest.param(SHIFTED, id="gap")])
def test_p2_elastic_contact_quantities_exact(make_config, changes):
    """pos_gc, energy_err, contact_force, contact_measure and penetration of a solved P2 level (N = 8) equal a
    brute force on its own u_h to 1e-10 relative (the gap case's pos_gc measured 5e-14 off; the brute force's
    zeros and maximum by Brent's method to 1e-15, its composite rule on smooth pieces moving by < 1e-14 from
    4000 to 16000 points)."""
    cfg = make_config(**merge(P2_ELASTIC, changes))
    level = refinement.solve_level(cfg, 0, 8, MPI.COMM_SELF, verifier=verification.Verifier(cfg))
    assert level.outcome.converged
    u_h = level.solution
    w, g0 = w_exact(changes)
    bottom = on_bottom(u_h)
    found = brute_force(lambda x: bottom(x) - g0(x), w, 8, cfg.alpha, level.eps)
    mu, lmbda = elasticity.lame(cfg.material)
    e = elasticity.exact_solution(cfg, u_h.function_space.mesh, level.eps) - u_h
    dx = ufl.Measure("dx", domain=u_h.function_space.mesh, metadata={"quadrature_degree": 12})
    a_ee = measure.integrate(ufl.inner(elasticity.sigma(e, mu, lmbda), elasticity.strain(e)), dx)
    alpha, x = cfg.alpha, level.extra
    assert x["pos_gc"] == pytest.approx(found["pos_power"] ** (1 / (alpha + 1)), rel=1e-10)
    assert x["energy_err"] == pytest.approx(np.sqrt(a_ee + found["pos_power"] / level.eps), rel=1e-10)
    for name in ("contact_force", "contact_measure", "penetration"):
        assert x[name] == pytest.approx(found[name], rel=1e-10), name


# 3-D: u·n = −u_z = −0.1 cos(2πx) cos(πy) on z = 0, a contact set whose edge is a curve across the facets
P2_ELASTIC_3D = {"dimension": 3, "mesh": {"kind": "unit_cube", "refinements": [2, 3]}, "problem": {
    "exact": ["0.1*sin(pi*x)*z", "0.05*sin(pi*y)*z", "0.1*cos(2*pi*x)*cos(pi*y)*(1 - z)**2"]}}


@pytest.mark.mpi
@pytest.mark.parametrize("changes", [pytest.param({"mesh": {"refinements": [4, 8]}}, id="2d"),
                                     pytest.param(P2_ELASTIC_3D, id="3d")])
def test_p2_elastic_two_ranks_equal_serial(make_config, changes):
    """Every error and Γ_C quantity of the P2 elastic study on 2 ranks is the serial one to 1e-10 relative."""
    cfg = make_config(**merge(P2_ELASTIC, changes))
    runs = [studies.run_study(cfg, comm=comm) for comm in (MPI.COMM_SELF, MPI.COMM_WORLD)]
    for one, two in zip(*runs):
        assert one.errors.keys() == two.errors.keys() and set(QUANTITIES) <= one.extra.keys()
        for name in one.errors:
            assert two.errors[name] == pytest.approx(one.errors[name], rel=1e-10), name
        for name in QUANTITIES:
            assert two.extra[name] == pytest.approx(one.extra[name], rel=1e-10), name
