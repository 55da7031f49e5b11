"""Γ_C measures: exact contact-set measure and penetration of P1 functions, the contact force, the
Γ_C errors; serial and on 2 ranks."""
import numpy as np
import pytest
import ufl
from mpi4py import MPI

from dolfinx import fem
from signorini_cli import config, measure, meshes, reference
from signorini_cli.meshes import CONTACT

# (mesh config, linear u with {u > 0} ∩ Γ_C of known measure, that measure, max of u on Γ_C)
CASES = [
    pytest.param(config.Mesh("unit_square"), lambda x: x[0] - 0.3, 0.7, 0.7, id="2d"),
    pytest.param(config.Mesh("unit_square", diagonal="crossed"), lambda x: 0.45 - x[0], 0.45, 0.45,
                 id="2d-crossed"),
    # on z = 0, {x + y > 0.5} is the unit square minus the triangle x + y <= 0.5 of area 1/8
    pytest.param(config.Mesh("unit_cube"), lambda x: x[0] + x[1] - 0.5, 0.875, 1.5, id="3d"),
]


def p1(domain, expression):
    V = fem.FunctionSpace(domain.mesh, ("Lagrange", 1))
    u = fem.Function(V)
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
    ds_c = domain.ds_c(measure.ERROR_DEGREE)
    # (1/eps) ∫_0^1 x^2 dx = 1/(3 eps): a polynomial the degree-8 quadrature integrates exactly
    assert measure.contact_force(u, 0.5, 2.0, ds_c) == pytest.approx(2 / 3, rel=1e-12)
    x = ufl.SpatialCoordinate(domain.mesh)
    found = measure.contact_errors(u, x[0], 0.5, 2.0, ds_c, 0.0)  # u_h = u on Γ_C: every error vanishes
    assert max(found.values()) < 1e-12
