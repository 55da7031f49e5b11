"""Problems posed right, or refused before solving: the data finite wherever the solve evaluates them,
and a manufactured Signorini solution that is one (u_S <= 0, ∂_n u_S <= 0, u_S ∂_n u_S = 0 on Γ_C)."""
import numpy as np
from mpi4py import MPI

import basix
import ufl
from dolfinx import fem

from ..config import ConfigError, expressions
from ..meshing.meshes import CONTACT, facet_vertices
from . import compliance, elasticity

# One-sided difference step for ∂_n u_S (domains are O(1)): its truncation error δ|u''|/2 and round-off
# 1e-16|u|/δ both stay near 1e-7 relative, far below SIGN_TOL.
STEP = 1e-7
SIGN_TOL = 1e-5  # relative to max(|u_S|, |∂_n u_S|) on Γ_C: a hundred times the difference's error


def check(cfg, domain, u_exact, eps_value, cells=True):
    """Raise ConfigError (on every rank) when the level's data are not finite at the points the solve
    and its errors evaluate them (the cells' quadrature points only with `cells`), or when a manufactured
    Signorini solution violates its conditions."""
    msh = domain.mesh
    if cfg.problem.exact is not None:
        _finite(msh, "problem.exact", cfg.problem.exact.text, _exact_at_vertices(cfg, msh, eps_value))
        if cells:
            f, _ = compliance.data(cfg, msh, eps_value, u_exact, ufl.FacetNormal(msh))
            _finite(msh, "problem.exact", f"f = -Δ({cfg.problem.exact.text})", _at_cell_points(msh, f))
            _finite(msh, "problem.exact", f"∇({cfg.problem.exact.text})", _at_cell_points(msh, ufl.grad(u_exact)))
    elif cells:
        f, g = compliance.data(cfg, msh, eps_value, None, ufl.FacetNormal(msh))
        for key, value in (("f", f), ("g", g)):
            if getattr(cfg.problem, key) is not None:
                _finite(msh, f"problem.{key}", getattr(cfg.problem, key).text, _at_cell_points(msh, value))
    if cfg.problem.exact_solves == "signorini":
        signorini_conditions(cfg, domain)


def check_elastic(cfg, domain, u_exact, eps_value, cells=True):
    """Raise ConfigError (on every rank) when an elastic problem's data are not finite where the solve and
    its errors evaluate them: u_ex's components and the gap g0 at the vertices, f = −div σ(u_ex) and ∇u_ex
    at the cells' quadrature points (with `cells`)."""
    msh = domain.mesh
    points = msh.geometry.x
    variables = dict(zip(("x", "y", "z"), points.T[:msh.geometry.dim]), eps=eps_value)
    functions = expressions.numpy_functions()
    data = [("problem.exact", c) for c in cfg.problem.exact or ()] + [("problem.gap", cfg.problem.gap)]
    for path, component in data:
        if component is not None:
            with np.errstate(all="ignore"):  # a nan is reported below, with its point
                values = np.asarray(component(variables, functions), dtype=float)
            _finite(msh, path, component.text, (points, np.broadcast_to(values, points.shape[:1])))
    if u_exact is not None and cells:
        mu, lmbda = elasticity.lame(cfg.material)
        f = -ufl.div(elasticity.sigma(u_exact, mu, lmbda))
        texts = ", ".join(c.text for c in cfg.problem.exact)
        _finite(msh, "problem.exact", f"f = -div σ(({texts}))", _at_cell_points(msh, f))
        _finite(msh, "problem.exact", f"∇(({texts}))", _at_cell_points(msh, ufl.grad(u_exact)))


def _exact_at_vertices(cfg, msh, eps_value):
    """(points, values) of u_ex at the mesh's vertices: the closed domain, Γ_D and Γ_C included."""
    points = msh.geometry.x
    with np.errstate(all="ignore"):  # a nan is reported below, with its point
        values = compliance.numpy_exact(cfg, msh.geometry.dim)(points, eps_value)
    return points, np.broadcast_to(np.asarray(values, dtype=float), points.shape[:1])


CHUNK = 1 << 14  # cells evaluated at once: the points and values of a chunk stay below ~10 MB in 3-D


def _at_cell_points(msh, value):
    """(points, values) of a UFL expression at the quadrature points of the data terms in the rank's cells:
    the first non-finite value found, or the last chunk's points when all are finite (evaluated chunk by
    chunk, so the check adds no more than a chunk to the peak memory)."""
    value = compliance.on_mesh(value, msh)
    cell = msh.topology.cell_name()
    X, _ = basix.make_quadrature(basix.cell.string_to_type(cell), compliance.QUADRATURE_DEGREE)
    size = int(np.prod(ufl.shape(value), dtype=int))  # explicit: a rank may own no cell (tiny meshes)
    where, what = fem.Expression(ufl.SpatialCoordinate(msh), X), fem.Expression(value, X)
    owned = msh.topology.index_map(msh.topology.dim).size_local
    points, pointwise = np.zeros((0, 3)), np.zeros(0)
    for start in range(0, owned, CHUNK):
        cells = np.arange(start, min(start + CHUNK, owned), dtype=np.int32)
        x = where.eval(cells).reshape(len(cells) * len(X), msh.geometry.dim)
        values = what.eval(cells).reshape(len(cells) * len(X), size)
        worst = np.argmax(~np.isfinite(values), axis=1)  # the first non-finite component of each point
        pointwise = np.take_along_axis(values, worst[:, None], axis=1)[:, 0]
        points = np.zeros((len(x), 3))
        points[:, :x.shape[1]] = x
        if not np.isfinite(pointwise).all():
            break
    return points, pointwise


def _finite(msh, path, text, found):
    """Refuse `text` (config key `path`) when any of its values is nan or infinite: name a point."""
    points, values = found
    bad = np.flatnonzero(~np.isfinite(values))
    first = (points[bad[0]], values[bad[0]]) if len(bad) else None
    every = [b for b in msh.comm.allgather(first) if b is not None]
    if every:
        point, value = every[0]
        raise ConfigError(path, f"{text} is {value} at {_point(point, msh.geometry.dim)}: the problem is "
                                "not defined there")


def signorini_conditions(cfg, domain):
    """u_S <= 0, ∂_n u_S <= 0 and u_S ∂_n u_S = 0 at the vertices and midpoints of Γ_C's facets (the
    ε → 0 limit of ε∂_n u + [u]_+^α = 0); refused naming the worst point."""
    msh = domain.mesh
    points, normals = contact_points(domain)
    u_S = compliance.numpy_exact(cfg, msh.geometry.dim)
    with np.errstate(all="ignore"):
        u = np.asarray(u_S(points, 0.0), dtype=float) * np.ones(len(points))
        flux = (u - u_S(points - STEP * normals, 0.0)) / STEP
    scale = max(msh.comm.allreduce(float(np.max(np.abs(np.r_[u, flux, 0.0]))), op=MPI.MAX), 1e-300)
    violations = (("u_S > 0 on Γ_C", u), ("∂_n u_S > 0 on Γ_C (a pull, not a contact pressure)", flux),
                  ("u_S ∂_n u_S != 0 on Γ_C (no complementarity)", np.abs(u * flux) / scale))
    for what, value in violations:
        k = int(np.argmax(value)) if len(value) else None
        local = (float(value[k]), points[k]) if k is not None else (-np.inf, None)
        worst, point = max(msh.comm.allgather(local), key=lambda item: item[0])
        if worst > SIGN_TOL * scale:
            raise ConfigError("problem.exact", f"not a Signorini solution: {what}, worst at "
                                               f"{_point(point, msh.geometry.dim)} ({worst:.3g})")


def contact_points(domain):
    """(points, outward unit normals) at the vertices and midpoints of this rank's Γ_C facets."""
    msh = domain.mesh
    tdim = msh.topology.dim
    facets = domain.facets(CONTACT)
    corners = facet_vertices(msh, facets)  # (facets, d, 3)
    if len(facets) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3))
    normals = _normals(corners, tdim)
    msh.topology.create_connectivity(tdim - 1, tdim)
    cells = np.array([msh.topology.connectivity(tdim - 1, tdim).links(f)[0] for f in facets])
    inward = _cell_centres(msh, cells) - corners.mean(axis=1)
    normals *= -np.sign(np.einsum("ij,ij->i", normals, inward))[:, None]
    midpoints = corners.mean(axis=1, keepdims=True)
    points = np.concatenate([corners, midpoints], axis=1)
    return points.reshape(-1, 3), np.repeat(normals, points.shape[1], axis=0)


def _normals(corners, tdim):
    """Unit normals of segments (2-D) or triangles (3-D), sign not yet chosen."""
    if tdim == 2:
        t = corners[:, 1] - corners[:, 0]
        n = np.stack([t[:, 1], -t[:, 0], np.zeros(len(t))], axis=1)
    else:
        n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def _cell_centres(msh, cells):
    from dolfinx import cpp
    dofs = cpp.mesh.entities_to_geometry(msh._mesh, msh.topology.dim, np.asarray(cells, dtype=np.int32), False)
    return msh.geometry.x[dofs].mean(axis=1)


def _point(point, dim):
    return "(" + ", ".join(f"{c:.4g}" for c in point[:dim]) + ")"
