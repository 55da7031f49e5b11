"""Γ_C measures: exact contact-set measure and penetration of P1 functions, the contact force, the
Γ_C errors; serial and on 2 ranks."""
import numpy as np
import pytest
import ufl
from mpi4py import MPI

import dolfinx.mesh
from dolfinx import fem
from signorini_cli import config
from signorini_cli.meshing import meshes
from signorini_cli.meshing.meshes import CONTACT
from signorini_cli.problems import contact, elasticity, element, measure
from signorini_cli.studies import refinement, verification
from signorini_cli.studies import reference

# (mesh config, linear u with {u > 0} ∩ Γ_C of known measure, that measure, max of u on Γ_C)
CASES = [
    pytest.param(config.Mesh("unit_square"), lambda x: x[0] - 0.3, 0.7, 0.7, id="2d"),
    pytest.param(config.Mesh("unit_square", diagonal="crossed"), lambda x: 0.45 - x[0], 0.45, 0.45,
                 id="2d-crossed"),
    # on z = 0, {x + y > 0.5} is the unit square minus the triangle x + y <= 0.5 of area 1/8
    pytest.param(config.Mesh("unit_cube"), lambda x: x[0] + x[1] - 0.5, 0.875, 1.5, id="3d"),
]


def p1(domain, expression):
    u = fem.Function(element.space(domain.mesh, 1))
    u.interpolate(expression)
    return u


def check_contact_set(mesh_cfg, expression, area, largest, comm):
    # N = 6: the zero lines x = 0.3, 0.45 and x + y = 0.5 cut facets, so the closed form is exercised
    domain = meshes.build(mesh_cfg, "bottom", 6, comm)
    u = p1(domain, expression)
    dofs, points = measure.contact_facet_dofs(u.function_space, domain.facet_tags, CONTACT)
    # a linear u is its own P1 interpolant, so the measure is exact: 1e-12 is round-off
    assert measure.contact_measure(u, dofs, points) == pytest.approx(area, rel=1e-12)
    assert measure.penetration(u, dofs.ravel()) == pytest.approx(largest, rel=1e-12)


@pytest.mark.parametrize("mesh_cfg, expression, area, largest", CASES)
def test_contact_set_exact_serial(mesh_cfg, expression, area, largest):
    check_contact_set(mesh_cfg, expression, area, largest, MPI.COMM_SELF)


@pytest.mark.mpi
@pytest.mark.parametrize("mesh_cfg, expression, area, largest", CASES)
def test_contact_set_exact_two_ranks(mesh_cfg, expression, area, largest):
    assert MPI.COMM_WORLD.size == 2
    check_contact_set(mesh_cfg, expression, area, largest, MPI.COMM_WORLD)


@pytest.mark.parametrize("values, fraction", [
    pytest.param([[1.0, 3.0]], 1.0, id="segment-inside"),
    pytest.param([[1.0, -3.0]], 0.25, id="segment-cut"),
    pytest.param([[0.0, -3.0]], 0.0, id="segment-touching"),
    pytest.param([[2.0, -1.0, -1.0]], 4 / 9, id="triangle-one-vertex"),
    pytest.param([[1.0, 1.0, -2.0]], 1 - 4 / 9, id="triangle-two-vertices"),
    pytest.param([[-1.0, -1.0, -1.0]], 0.0, id="triangle-outside"),
])
def test_positive_fraction(values, fraction):
    assert measure.positive_fraction(np.array(values))[0] == pytest.approx(fraction, rel=1e-14)


def test_contact_force_and_errors_of_a_known_function():
    domain = meshes.build(config.Mesh("unit_square"), "bottom", 4, MPI.COMM_SELF)
    u = p1(domain, lambda x: x[0])
    # ∫_0^1 x^2 dx = 1/3, in closed form for the P1 function
    dofs, points = measure.contact_facet_dofs(u.function_space, domain.facet_tags, CONTACT)
    assert contact.positive_power(MPI.COMM_SELF, u.x.array[dofs], points, 2.0) == pytest.approx(1 / 3, rel=1e-14)
    found = measure.contact_errors(MPI.COMM_SELF, points, u.x.array[dofs], lambda facets, x: x[..., 0], 0.5, 2.0,
                                   0.0)  # u_h = u on Γ_C: every error vanishes
    assert max(found.values()) < 1e-12


# --- the error quadrature -------------------------------------------------------------------------

@pytest.mark.parametrize("kind, n, k, degree", [("unit_square", 32, 1, 8),   # h = 0.044
                                                ("unit_square", 64, 1, 6),   # h = 0.022
                                                ("unit_cube", 32, 1, 8),     # h = 0.054
                                                ("unit_cube", 64, 1, 6),     # h = 0.027
                                                ("unit_square", 32, 2, 10),
                                                ("unit_square", 64, 2, 8),
                                                ("unit_cube", 4, 2, 14),     # h = 0.43
                                                ("unit_cube", 8, 2, 12)])    # h = 0.22
def test_error_degree_by_level(kind, n, k, degree):
    domain = meshes.build(config.Mesh(kind), "bottom", n, MPI.COMM_SELF)
    assert measure.error_degree(element.space(domain.mesh, k), domain.h) == degree


@pytest.mark.parametrize("comm", [pytest.param(MPI.COMM_SELF, id="serial"),
                                  pytest.param(MPI.COMM_WORLD, id="world", marks=pytest.mark.mpi)])
def test_fine_level_errors_as_with_degree_12(comm):
    """On a fine level the cheaper rule gives the errors of a far more accurate one to 1e-9 relative
    (the bench problem's u_ex; its interpolant stands in for u_h: the same P1-minus-smooth integrand)."""
    domain = meshes.build(config.Mesh("unit_square"), "bottom", 64, comm)
    x = ufl.SpatialCoordinate(domain.mesh)
    u_ex = ufl.sin(2 * np.pi * x[0]) * (1 - x[1]) ** 2
    u_h = p1(domain, lambda p: np.sin(2 * np.pi * p[0]) * (1 - p[1]) ** 2)
    dx = ufl.Measure("dx", domain=domain.mesh, metadata={"quadrature_degree": 12})
    e = u_h - u_ex
    accurate = {"L2": np.sqrt(measure.integrate(e**2, dx)),
                "H1": np.sqrt(measure.integrate(ufl.inner(ufl.grad(e), ufl.grad(e)), dx))}
    assert measure.errors(u_h, u_ex, domain.h) == pytest.approx(accurate, rel=1e-9)


@pytest.mark.parametrize("comm", [pytest.param(MPI.COMM_SELF, id="serial"),
                                  pytest.param(MPI.COMM_WORLD, id="world", marks=pytest.mark.mpi)])
@pytest.mark.parametrize("kind, n", [("unit_square", 16), ("unit_cube", 4)])
def test_integrals_together_as_one_by_one(comm, kind, n):
    """The one-pass integrals of measure.errors are assemble_scalar's: the same cell sums, added in another
    order (observed 1e-14 relative at most)."""
    domain = meshes.build(config.Mesh(kind), "bottom", n, comm)
    x = ufl.SpatialCoordinate(domain.mesh)
    u_ex = ufl.sin(2 * np.pi * x[0]) * (1 - x[1]) ** 2
    e = p1(domain, lambda p: 1.01 * np.sin(2 * np.pi * p[0]) * (1 - p[1]) ** 2) - u_ex
    dx = ufl.Measure("dx", domain=domain.mesh, metadata={"quadrature_degree": 8})
    exprs = [e**2, ufl.inner(ufl.grad(e), ufl.grad(e)), e]
    together = measure.integrate_together(domain.mesh, exprs, dx)
    assert together == pytest.approx([measure.integrate(expr, dx) for expr in exprs], rel=1e-13)


# --- Γ_C errors of a solved level against a brute-force integral of its own u_h ----------------------

def brute_force(points, values, exact, alpha, eps, per_facet=10**5):
    """(∫|[w]_+ − [w_h]_+|^(alpha+1), (1/eps)∫[w_h]_+^alpha) over segments: composite 2-point Gauss-Legendre
    with per_facet points on each facet, w_h linear between its vertex values."""
    halves = per_facet // 2
    t = ((np.arange(halves)[:, None] + 0.5 + np.array([-0.5, 0.5]) / np.sqrt(3)) / halves).ravel()
    power = force = 0.0
    for (p0, p1), (v0, v1) in zip(points, values):
        w_h = (1 - t) * v0 + t * v1
        w = exact(p0 + t[:, None] * (p1 - p0))
        length = np.linalg.norm(p1 - p0)
        power += length * np.mean(np.abs(np.maximum(w, 0) - np.maximum(w_h, 0)) ** (alpha + 1))
        force += length * np.mean(np.maximum(w_h, 0) ** alpha) / eps
    return power, force


ELASTIC_STIFF = {"epsilon": {"law": "constant", "theta": 1e-8}, "problem": {
    "pde": "elasticity", "exact": ["0.1*sin(pi*x)*y", "0.1*cos(2*pi*x)*(1 - y)**2"]},
    "material": {"E": 1.0, "nu": 0.3}, "solver": {"strategy": "auto"},
    "verification": {"measures": ["pos_gc", "energy_err", "contact_force"]}}


@pytest.mark.parametrize("changes, exact", [
    pytest.param({"verification": {"measures": ["pos_gc", "energy_err", "contact_force"]}},
                 lambda x: np.sin(2 * np.pi * x[:, 0]), id="demo"),
    pytest.param(ELASTIC_STIFF, lambda x: -0.1 * np.cos(2 * np.pi * x[:, 0]), id="elastic-stiff"),
])
def test_contact_errors_of_a_solved_level_exact(make_config, changes, exact):
    """pos_gc, energy_err and contact_force of the product's own u_h (demo: N = 16; the stiff elastic case:
    w = u·n on y = 0, n = (0, -1)) agree with a brute-force integral to 1e-10 relative (the composite rule's
    own error at the kinks is below 1e-12 with 10^5 points per facet)."""
    cfg = make_config(**changes)
    level = refinement.solve_level(cfg, 0, 16, MPI.COMM_SELF, verifier=verification.Verifier(cfg))
    u_h = level.solution
    msh = u_h.function_space.mesh
    bottom = dolfinx.mesh.locate_entities_boundary(msh, 1, lambda x: np.isclose(x[1], 0.0))
    tags = dolfinx.mesh.meshtags(msh, 1, bottom, np.full(len(bottom), CONTACT, dtype=np.int32))
    dofs, points = measure.contact_facet_dofs(element.space(msh, 1), tags, CONTACT)
    if u_h.function_space.dofmap.index_map_bs == 2:  # w_h = u_h·n with n = (0, -1); a(e, e) the seminorm
        values = -u_h.x.array.reshape(-1, 2)[dofs, 1]
        mu, lmbda = elasticity.lame(cfg.material)
        e = elasticity.exact_solution(cfg, msh, level.eps) - u_h
        dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": 8})
        seminorm = np.sqrt(measure.integrate(ufl.inner(elasticity.sigma(e, mu, lmbda), elasticity.strain(e)), dx))
    else:
        values, seminorm = u_h.x.array[dofs], level.errors["H1"]
    power, force = brute_force(points, values, exact, cfg.alpha, level.eps)
    alpha = cfg.alpha
    assert level.extra["pos_gc"] == pytest.approx(power ** (1 / (alpha + 1)), rel=1e-10)
    assert level.extra["contact_force"] == pytest.approx(force, rel=1e-10)
    assert level.extra["energy_err"] == pytest.approx(np.sqrt(seminorm**2 + power / level.eps), rel=1e-10)
