"""Hertz's measured quantities: the central pressure p_h reads Hertz's p0 back from Hertz's own profile."""
import numpy as np
import pytest
from mpi4py import MPI

from dolfinx import fem, mesh

from signorini_cli.meshing import meshes
from signorini_cli.problems import contact, hertz

EPS, P0, A, CENTRE = 1e-3, 2.0, 0.3, 0.5


def hertz_term(dim, n):
    """A contact term on the face z = 0 (y = 0 in 2-D) of the unit square or cube, with normal −e_d, whose
    solution presses with Hertz's p0 (1 − r²/a²)^(1/2) about (0.5, 0.5): w = −u_d = ε p for α = 1."""
    comm = MPI.COMM_WORLD
    domain = (mesh.create_unit_square(comm, n, 2) if dim == 2 else mesh.create_unit_cube(comm, n, n, 1))
    face = mesh.locate_entities_boundary(domain, dim - 1, lambda x: np.isclose(x[dim - 1], 0.0))
    tags = mesh.meshtags(domain, dim - 1, face, np.full(len(face), meshes.CONTACT, dtype=np.int32))
    u_h = fem.Function(fem.VectorFunctionSpace(domain, ("Lagrange", 1)))

    def pressed(x):
        r2 = sum((x[i] - CENTRE) ** 2 for i in range(dim - 1))
        u = np.zeros((dim, x.shape[1]))
        u[dim - 1] = -EPS * P0 * np.sqrt(np.clip(1 - r2 / A**2, 0, None))
        return u
    u_h.interpolate(pressed)
    term = contact.ContactTerm(u_h, tags, meshes.CONTACT, 1.0, EPS)
    term.normal = np.tile(-np.eye(dim)[dim - 1], (len(term.dofs), 1))
    return term


@pytest.mark.parametrize("dim, n, tol", [(2, 256, 6e-5), (3, 64, 2e-3)])
def test_central_pressure_is_hertz_p0_on_hertz_profile(dim, n, tol):
    """h = 1/256 (2-D), 1/64 (3-D): |p_h − p0|/p0 measured 3.0e-5 and 1.0e-3 (the P1 interpolants of the profile
    and of the weight: 4× smaller per halving of h, measured from h = 1/64 and 1/16); the contact set is centred
    on the profile's centre and a_h is within two cells of a (the interpolant's zero lies beyond a)."""
    term = hertz_term(dim, n)
    w, m0, m1 = hertz.facet_moments(term, 1.0)
    force, a_h, centre, normal = hertz.measured(term, w, m0, EPS, dim, MPI.COMM_WORLD)
    assert np.allclose(centre[:dim - 1], CENTRE, atol=1e-12) and abs(a_h - A) < 2 / n
    p_h = hertz.central_pressure(term, m1, EPS, centre, normal, A, MPI.COMM_WORLD)
    assert abs(p_h / P0 - 1) < tol
