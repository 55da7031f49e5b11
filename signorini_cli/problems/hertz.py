"""Hertz's contact of an elastic cylinder (2-D, plane strain, per unit length) or sphere (3-D) of radius R and
a plane (or of a rigid cylinder or sphere and an elastic half-space), and what a solve measures of it:
the contact half-width a, the peak pressure p0 and the total force F (Johnson, Contact Mechanics, §4.2, §5.2)."""
import math

import numpy as np
from mpi4py import MPI

from ..config import names
from . import contact, elasticity, kinked

COLUMNS = names.HERTZ[1:]  # after contact_force: a_h, a, its error, p_h, p0, its error, F(a_h), its error


def effective_modulus(material):
    """E* = E/(1 − ν²) against a rigid body."""
    return material.E / (1 - material.nu**2)


def closed_form(force, radius, material, dim):
    """(a, p0) under the force F: 2-D a = 2(RF/(πE*))^(1/2), p0 = 2F/(πa); 3-D a = (3FR/(4E*))^(1/3),
    p0 = 3F/(2πa²)."""
    E_star = effective_modulus(material)
    if dim == 2:
        a = 2 * math.sqrt(radius * force / (math.pi * E_star))
        return a, 2 * force / (math.pi * a) if a > 0 else 0.0
    a = (3 * force * radius / (4 * E_star)) ** (1 / 3)
    return a, 3 * force / (2 * math.pi * a**2) if a > 0 else 0.0


def force_of(half_width, radius, material, dim):
    """Hertz's force for the half-width a (the inverse of closed_form's a): πE*a²/(4R) in 2-D, 4E*a³/(3R) in 3-D."""
    E_star = effective_modulus(material)
    return math.pi * E_star * half_width**2 / (4 * radius) if dim == 2 else 4 * E_star * half_width**3 / (3 * radius)


def facet_moments(term, alpha):
    """(w, m0, m1): the vertex values w_h = u_h·n − g0 of the Γ_C facets (facets, k), and the means over each
    facet of [w_h]_+^α and of [w_h]_+^α λ_i (contact.moments), which measured and central_pressure share."""
    w = term.values(term.u_h.x.array)
    m0, m1, _ = contact.moments(w, alpha) if len(w) else (np.zeros(0), np.zeros(w.shape), None)
    return w, m0, m1


def measured(term, w, m0, eps, dim, comm):
    """(F_h, a_h, centre, n) of the P1 solution on Γ_C (w, m0 of facet_moments): F_h = (1/ε)∫[w_h]_+^α in
    closed form, a_h the largest distance, across the mean normal n, of the contact set's boundary (the zeros
    of the linear w_h on the facets' edges) from the centre of its bounding box."""
    x = term.points[..., :dim]
    force = comm.allreduce(float(np.sum(term.sizes * m0)), op=MPI.SUM) / eps
    ends = np.concatenate(comm.allgather(boundary_points(w, x)))
    normals = np.concatenate(comm.allgather(term.normal)).sum(axis=0)
    n = normals / np.linalg.norm(normals)
    if not len(ends):
        return force, 0.0, None, n
    centre = (ends.min(axis=0) + ends.max(axis=0)) / 2
    return force, float(np.linalg.norm(across(ends - centre, n), axis=1).max()), centre, n


def central_pressure(term, m1, eps, centre, n, a, comm):
    """p_h = ∫p_h ψ / (c ∫ψ): the contact pressure p_h = (1/ε)[w_h]_+^α (m1 of facet_moments) averaged with the
    weight ψ = (1 − (2r/a)²)_+² (its P1 interpolant; r the distance from the contact centre across n) over the
    central half of Hertz's contact zone, over c, the same mean of Hertz's profile (1 − r²/a²)^(1/2): p_h = p0
    for Hertz's pressure. An average, not the largest nodal value: at small ε the vertex pressures swing from
    vertex to vertex on tetrahedra (0.02 to 0.15 against Hertz's 0.073 in the 3-D Hertz study) and their
    maximum does not converge."""
    k = m1.shape[1]
    force, _ = elasticity.on_vertices(term, term.sizes[:, None] * m1 / eps)  # λ_i = ∫p_h φ_i
    area, _ = elasticity.on_vertices(term, np.repeat(term.sizes[:, None] / k, k, axis=1))  # ∫φ_i
    space = force.function_space
    owned = space.dofmap.index_map.size_local
    r = np.linalg.norm(across(space.tabulate_dof_coordinates()[:owned, :len(n)] - centre, n), axis=1)
    psi = np.clip(1 - (2 * r / a) ** 2, 0, None) ** 2
    sums = comm.allreduce(np.array([force.x.array[:owned] @ psi, area.x.array[:owned] @ psi]), op=MPI.SUM)
    return sums[0] / (sums[1] * hertz_mean(len(n)))


def hertz_mean(dim):
    """c = ∫(1 − s²)^(1/2) ψ / ∫ψ over the central half s = r/a ≤ 1/2 of the contact zone, ψ = (1 − 4s²)²,
    along a line (2-D) or over a disk (3-D, weight s): Gauss–Legendre, exact to round-off (smooth on s ≤ 1/2)."""
    t, weights = np.polynomial.legendre.leggauss(20)
    s = (t + 1) / 4
    measure = weights * (1 - 4 * s**2) ** 2 * (s if dim == 3 else 1.0)
    return float(measure @ np.sqrt(1 - s**2) / measure.sum())


def across(x, n):
    """The components of the points x (m, d) across the unit normal n."""
    return x - np.outer(x @ n, n)


def boundary_points(w, x):
    """The points where the facets' linear w (facets, k) changes sign along their edges, and their vertices
    with w > 0 (x: the vertices' points, (facets, k, d)): the contact set's extent."""
    pairs = [(i, j) for i in range(w.shape[1]) for j in range(i + 1, w.shape[1])]
    cuts = [kinked.edge_zero(x, w, i, j)[1] for i, j in pairs]
    return np.concatenate([x[w > 0]] + [at[np.isfinite(at[:, 0])] for at in cuts])


def quantities(cfg, term, eps):
    """The Hertz columns of a level (COLUMNS): a_h and the central pressure p_h against Hertz's a, p0 of the
    measured force F_h, and F_h against Hertz's force of the measured a_h; relative errors |q_h − q|/q."""
    comm, dim, R = term.u_h.function_space.mesh.comm, cfg.dimension, cfg.problem.hertz_radius
    w, m0, m1 = facet_moments(term, cfg.alpha)
    force, a_h, centre, n = measured(term, w, m0, eps, dim, comm)
    a, p0 = closed_form(force, R, cfg.material, dim)
    p_h = central_pressure(term, m1, eps, centre, n, a, comm) if centre is not None else 0.0
    f = force_of(a_h, R, cfg.material, dim)
    return dict(zip(COLUMNS, (a_h, a, relative(a_h, a), p_h, p0, relative(p_h, p0), f, relative(force, f))))


def relative(value, exact):
    return abs(value - exact) / exact if exact > 0 else None
