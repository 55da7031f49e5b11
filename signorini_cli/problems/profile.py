"""The contact pressure along Γ_C, p_h = (1/ε)[w_h]_+^α at the Γ_C nodes (w = u for the scalar problem,
u·n − g0 for elasticity), with the exact (1/ε)[w_ex]_+^α where u_ex is given: the rows of a pressure profile
(report/pressure.py draws them), against a position on Γ_C: x along a 2-D face (its tangent), the distance
from the centre of the contact set in 3-D (a radial plot)."""
import numpy as np

from ..config import expressions
from ..meshing.meshes import CONTACT
from . import elasticity, measure


def rows(cfg, domain, u_h, forms, eps_value, index):
    """[{level, x (2-D) or r (3-D), pressure[, pressure_exact]}] of the level's Γ_C nodes, sorted by position,
    on every rank (gathered)."""
    comm = domain.mesh.comm
    points, values = (_elastic(cfg, forms, eps_value) if forms.gap is not None
                      else _scalar(cfg, domain, u_h, forms, eps_value))
    points = np.concatenate(comm.allgather(points))
    values = np.concatenate(comm.allgather(values))
    _, first = np.unique(points.round(12), axis=0, return_index=True)  # a node seen by two ranks: once
    points, values = points[first], values[first]
    position = positions(points, values[:, 0], domain)
    order = np.argsort(position, kind="stable")
    names = ("r" if domain.mesh.geometry.dim == 3 else "x", "pressure", "pressure_exact")[:1 + values.shape[1]]
    return [dict(level=index, **dict(zip(names, map(float, (position[k], *values[k]))))) for k in order]


def elastic_pressure(cfg, forms, eps_value):
    """p_h = (1/ε)[u_h·n − g0]_+^α as a P1 function: its Γ_C facets' values averaged at each node, 0 elsewhere
    (the normal is the facets' own, which a UFL expression cannot interpolate)."""
    sums, counts = elasticity.on_vertices(forms.gap.term, elasticity.pressure_values(cfg, forms.gap.term, eps_value))
    np.divide(sums.x.array, counts.x.array, out=sums.x.array, where=counts.x.array > 0)
    sums.name = "pressure"
    return sums


def _elastic(cfg, forms, eps_value):
    """The owned Γ_C nodes' points and pressures (nodes, 1 or 2), a node's facets averaged."""
    term = forms.gap.term
    found = [elasticity.pressure_values(cfg, term, eps_value)]
    if forms.u_exact is not None:
        found.append(elasticity.pressure_values(cfg, term, eps_value, u_exact=True))
    counts = None
    columns = []
    for values in found:
        sums, counts = elasticity.on_vertices(term, values)
        columns.append(sums.x.array)
    Q = counts.function_space
    owned = np.flatnonzero(counts.x.array[:Q.dofmap.index_map.size_local] > 0)
    x = Q.tabulate_dof_coordinates()[owned]
    return x, np.stack([c[owned] / counts.x.array[owned] for c in columns], axis=1)


def _scalar(cfg, domain, u_h, forms, eps_value):
    """The Γ_C dofs' points and pressures (dofs, 1 or 2) of this rank's Γ_C facets."""
    V = u_h.function_space
    dofs, points = measure.contact_facet_dofs(V, domain.facet_tags, CONTACT)
    dofs, first = np.unique(dofs.ravel(), return_index=True)
    x = points.reshape(-1, 3)[first]  # ghosts too: a Γ_C node whose facets another rank owns
    columns = [_pressure(u_h.x.array[dofs], cfg.alpha, eps_value)]
    if forms.u_exact is not None:
        variables = dict(zip(("x", "y", "z"), x.T), eps=eps_value)
        exact = np.broadcast_to(cfg.problem.exact(variables, expressions.numpy_functions()), len(x))
        columns.append(_pressure(exact, cfg.alpha, eps_value))
    return x, np.stack(columns, axis=1)


def _pressure(w, alpha, eps_value):
    return np.maximum(w, 0.0) ** alpha / eps_value


def positions(points, pressure, domain):
    """Where each point lies on Γ_C: in 2-D its coordinate along the tangent of Γ_C's mean normal (x on
    the bottom face, increasing along the axis the tangent is closest to); in 3-D its distance, across the
    mean normal, from the centre of the bounding box of the points in contact (of all points without)."""
    msh = domain.mesh
    d = msh.geometry.dim
    facets = elasticity.owned_contact_facets(domain)
    normals = np.concatenate(msh.comm.allgather(elasticity.facet_normals(msh, facets)))
    n = normals.sum(axis=0)
    n /= np.linalg.norm(n)
    x = points[:, :d]
    if d == 2:
        t = np.array([-n[1], n[0]])
        return x @ (t if t[np.argmax(np.abs(t))] > 0 else -t)
    touching = x[pressure > 0] if np.any(pressure > 0) else x
    r = x - (touching.min(axis=0) + touching.max(axis=0)) / 2
    r -= np.outer(r @ n, n)
    return np.linalg.norm(r, axis=1)
