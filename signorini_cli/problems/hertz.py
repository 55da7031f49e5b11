"""Hertz's contact of an elastic cylinder (2-D, plane strain, per unit length) or sphere (3-D) of radius R and
a plane (or of a rigid cylinder or sphere and an elastic half-space), and what a solve measures of it:
the contact half-width a, the peak pressure p0 and the total force F (Johnson, Contact Mechanics, §4.2, §5.2)."""
import math

import numpy as np
from mpi4py import MPI

from ..config import names
from . import contact, elasticity

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


def measured(term, eps, alpha, dim, comm):
    """(F_h, a_h, p_h) of the P1 solution on Γ_C from the vertex values w_h = u_h·n − g0 of its facets:
    F_h = (1/ε)∫[w_h]_+^α in closed form, a_h the largest distance, across the mean normal, of the contact
    set's boundary (the zeros of the linear w_h on the facets' edges) from the centre of its bounding box, p_h
    the largest nodal pressure λ_i/∫φ_i, λ_i = (1/ε)∫[w_h]_+^α φ_i the vertex's contact force (as the VI's
    pressure is measured: the vertex values (1/ε)[w_i]_+^α oscillate from vertex to vertex when ε
    is small, measured 0.22 against Hertz's 0.075 on the 3-D Hertz base mesh at ε = 1e-5, the nodal one 0.086)."""
    w, x = term.values(term.u_h.x.array), term.points[..., :dim]
    moments = contact.moments(w, alpha) if len(w) else (np.zeros(0), np.zeros(w.shape))
    force = comm.allreduce(float(np.sum(term.sizes * moments[0])), op=MPI.SUM) / eps
    nodal, area = elasticity.on_vertices(term, term.sizes[:, None] * moments[1] / eps)
    weights, _ = elasticity.on_vertices(term, np.repeat(term.sizes[:, None] / w.shape[1], w.shape[1], axis=1))
    on = weights.x.array > 0
    peak = comm.allreduce(float((nodal.x.array[on] / weights.x.array[on]).max(initial=0.0)), op=MPI.MAX)
    ends = np.concatenate(comm.allgather(boundary_points(w, x)))
    if not len(ends):
        return force, 0.0, peak
    normals = np.concatenate(comm.allgather(term.normal)).sum(axis=0)
    n = normals / np.linalg.norm(normals)
    r = ends - (ends.min(axis=0) + ends.max(axis=0)) / 2
    r -= np.outer(r @ n, n)
    return force, float(np.linalg.norm(r, axis=1).max()), peak


def boundary_points(w, x):
    """The points where the facets' linear w (facets, k) changes sign along their edges, and their vertices
    with w > 0 (x: the vertices' points, (facets, k, d)): the contact set's extent."""
    found = [x[w > 0]]
    for i in range(w.shape[1]):
        for j in range(i + 1, w.shape[1]):
            cut = (w[:, i] > 0) != (w[:, j] > 0)
            t = w[cut, i] / (w[cut, i] - w[cut, j])
            found.append(x[cut, i] + t[:, None] * (x[cut, j] - x[cut, i]))
    return np.concatenate(found)


def quantities(cfg, term, eps):
    """The Hertz columns of a level (COLUMNS): a_h and p_h against Hertz's a, p0 of the measured force F_h,
    and F_h against Hertz's force of the measured a_h; relative errors |q_h − q|/q."""
    comm, dim, R = term.u_h.function_space.mesh.comm, cfg.dimension, cfg.problem.hertz_radius
    force, a_h, p_h = measured(term, eps, cfg.alpha, dim, comm)
    a, p0 = closed_form(force, R, cfg.material, dim)
    f = force_of(a_h, R, cfg.material, dim)
    return dict(zip(COLUMNS, (a_h, a, relative(a_h, a), p_h, p0, relative(p_h, p0), f, relative(force, f))))


def relative(value, exact):
    return abs(value - exact) / exact if exact > 0 else None
