"""Problems posed right, or refused before solving: the data finite wherever the solve evaluates them, their
integrals settled with the quadrature degree (which the data choose: Profile), and a manufactured Signorini
solution that is one (u_S <= 0, ∂_n u_S <= 0, u_S ∂_n u_S = 0 on Γ_C)."""
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

import basix
import ufl
from dolfinx import fem

from ..config import ConfigError, expressions
from ..meshing.meshes import CONTACT, facet_vertices
from . import compliance, elasticity, element, forms

# One-sided difference step for ∂_n u_S (domains are O(1)): its truncation error δ|u''|/2 and round-off
# 1e-16|u|/δ both stay near 1e-7 relative, far below SIGN_TOL.
STEP = 1e-7
SIGN_TOL = 1e-5  # relative to max(|u_S|, |∂_n u_S|) on Γ_C: a hundred times the difference's error


# The data's integrals must settle with the quadrature degree: raising it from 16 to 20 changes the load
# vector of smooth data by round-off on the coarsest mesh of a family (measured: 7.8e-16 relative for the
# demo's N = 8, 3.9e-13 for the elastic cube's N = 2), that of an unbounded f by 2e-2 .. 5e-2
# ((|x - 0.3|^1.5 - 0.1)(1-y)²: f ~ |x - 0.3|^-1/2 along x = 0.3; r^(2/3)(1-y) at a corner)
SETTLE_DEGREES = (16, 20)
SETTLE_TOL = 1e-8


def check(cfg, domain, u_exact, eps_value, coarsest=None):
    """Raise ConfigError (on every rank) when the level's data are not finite at the points the solve
    and its errors evaluate them, or do not settle with the quadrature degree (on the family's `coarsest`
    Domain, when given: once per family), or when a manufactured Signorini solution violates its conditions."""
    msh = domain.mesh
    if cfg.problem.exact is not None:
        _finite(msh, "problem.exact", cfg.problem.exact.text, _exact_at_vertices(cfg, msh, eps_value))
    found = _check_cells(cfg, coarsest, eps_value) if coarsest is not None else None
    if cfg.problem.exact_solves == "signorini":
        signorini_conditions(cfg, domain)
    return found


def _check_cells(cfg, coarsest, eps_value):
    """The scalar data finite at the cells' quadrature points of the coarsest mesh, and their load settled;
    their Profile."""
    msh = coarsest.mesh
    V = compliance.space(cfg, msh)
    v = ufl.TestFunction(V)
    if cfg.problem.exact is not None:
        text = cfg.problem.exact.text
        u_exact = compliance.exact_solution(cfg, msh, eps_value)
        f, _ = compliance.data(cfg, msh, eps_value, u_exact, ufl.FacetNormal(msh))
        _finite(msh, "problem.exact", f"f = -Δ({text})", _at_cell_points(msh, f))
        _finite(msh, "problem.exact", f"∇({text})", _at_cell_points(msh, ufl.grad(u_exact)))
        _settles(V, "problem.exact", f"f = -Δ({text})", forms.on_mesh(f, msh) * v,
                 ufl.inner(ufl.grad(u_exact), ufl.grad(v)))
        numpy_exact = compliance.numpy_exact(cfg, msh.geometry.dim)
        return profile(cfg, coarsest, forms.on_mesh(f, msh), u_exact,
                       lambda points: np.asarray(numpy_exact(points, eps_value), dtype=float)[..., None]
                       * np.ones(points.shape[:-1] + (1,)))
    f, g = compliance.data(cfg, msh, eps_value, None, ufl.FacetNormal(msh))
    for key, value in (("f", f), ("g", g)):
        if getattr(cfg.problem, key) is not None:
            _finite(msh, f"problem.{key}", getattr(cfg.problem, key).text, _at_cell_points(msh, value))
    _settles(V, "problem.f", cfg.problem.f.text, forms.on_mesh(f, msh) * v, None)
    return profile(cfg, coarsest, forms.on_mesh(f, msh), None, None)


def _settles(V, path, text, load, balance):
    """Refuse data whose load ∫ load(v) dx on V changes by more than SETTLE_TOL between the Gauss rules of
    SETTLE_DEGREES: no rule integrates it to the precision the study reports. Relative to the largest entry
    of the load, or of `balance` (a(u_ex, v): what the load balances; a harmonic u_ex has a load of round-off)."""
    msh = V.mesh
    owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs

    def assembled(integrand, q):
        if isinstance(integrand, ufl.constantvalue.Zero):  # UFL's 0·v: the load of a constant or linear u_ex
            return np.zeros(owned)
        dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": q})
        return fem.assemble_vector(fem.form(integrand * dx)).array[:owned]
    loads = [assembled(load, q) for q in SETTLE_DEGREES]
    change = np.abs(loads[1] - loads[0])
    largest = np.abs(loads[1]) if balance is None else np.abs(np.r_[loads[1], assembled(balance, SETTLE_DEGREES[0])])
    scale = msh.comm.allreduce(float(largest.max(initial=0.0)), op=MPI.MAX)
    k = int(np.argmax(change)) if len(change) else None
    local = (float(change[k]), V.tabulate_dof_coordinates()[k // V.dofmap.index_map_bs]) if k is not None else \
        (-1.0, None)
    worst, where = max(msh.comm.allgather(local), key=lambda item: item[0])
    if worst > SETTLE_TOL * scale:
        low, high = SETTLE_DEGREES
        raise ConfigError(path, f"the load of {text} does not settle: quadrature degree {low} -> {high} changes "
                                f"it by {worst / scale:.1e} relative (most near {_point(where, msh.geometry.dim)});"
                                " the data are not smooth enough (unbounded?) for the error the study reports")


def check_elastic(cfg, domain, u_exact, eps_value, coarsest=None):
    """Raise ConfigError (on every rank) when an elastic problem's data are not finite where the solve and
    its errors evaluate them: u_ex's components and the gap g0 at the vertices, f = −div σ(u_ex) and ∇u_ex
    at the quadrature points of the family's `coarsest` cells (when given: once per family), whose load
    ∫ σ(u_ex):ε(v) must also settle with the quadrature degree."""
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
    if cfg.problem.exact is not None and coarsest is not None:
        msh = coarsest.mesh
        u_c = elasticity.exact_solution(cfg, msh, eps_value)
        mu, lmbda = elasticity.lame(cfg.material)
        texts = ", ".join(c.text for c in cfg.problem.exact)
        _finite(msh, "problem.exact", f"f = -div σ(({texts}))", _at_cell_points(msh, -ufl.div(
            elasticity.sigma(u_c, mu, lmbda))))
        _finite(msh, "problem.exact", f"∇(({texts}))", _at_cell_points(msh, ufl.grad(u_c)))
        V = elasticity.space(cfg, msh)
        v = ufl.TestFunction(V)
        f = -ufl.div(elasticity.sigma(u_c, mu, lmbda))
        _settles(V, "problem.exact", f"f = -div σ(({texts}))", ufl.inner(f, v),
                 ufl.inner(elasticity.sigma(u_c, mu, lmbda), elasticity.strain(v)))

        def components(points):
            variables = dict(zip(("x", "y", "z"), np.moveaxis(points, -1, 0)[:msh.geometry.dim]), eps=eps_value)
            return np.stack([np.broadcast_to(c(variables, functions), points.shape[:-1])
                             for c in cfg.problem.exact], axis=-1)
        return profile(cfg, coarsest, f, u_c, components)
    return None


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
    value = forms.on_mesh(value, msh)
    cell = msh.topology.cell_name()
    X, _ = basix.make_quadrature(basix.cell.string_to_type(cell), forms.QUADRATURE_DEGREE)
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


# --- the quadrature degree the data need --------------------------------------------------------------

CANDIDATES = (6, 8, 10, 12, 14, 16)  # the Gauss degrees a level's data integrals may take
REFERENCE_DEGREE = 20
DATA_TOL = 1e-10  # the relative change against REFERENCE_DEGREE a level's load and error integrals may keep
PROFILE_VALUES = 1 << 20  # values evaluated at once (8 MB; all rules' points of a cell: ~260 in 2-D, ~3300 in 3-D)


@dataclass(frozen=True)
class Profile:
    """How the data's integrals settle with the Gauss degree, measured once on a family's coarsest mesh (size
    h0): the relative change of the load (per cell and basis function) and of the error integrals of u_ex's
    interpolant (L2 and H1) at each candidate degree against REFERENCE_DEGREE."""
    h0: float
    load: dict
    error: dict
    k: int  # the element degree

    def degrees(self, h, load_low, error_low):
        """(load degree, error degree) of a level of size h: the lowest candidates, not below the defaults,
        whose change scaled to h as a Gauss rule's error on smooth data, (h/h0)^(q+1) for the load and
        (h/h0)^(q-k) relative to an error integral of order h^(2k+2), stays below DATA_TOL."""
        def lowest(changes, low, power):
            fits = [q for q in CANDIDATES if q >= low and changes.get(q, 0.0) * (h / self.h0) ** power(q) <= DATA_TOL]
            return max(low, fits[0] if fits else CANDIDATES[-1])
        return (lowest(self.load, load_low, lambda q: q + 1),
                lowest(self.error, error_low, lambda q: max(q - self.k, 1)) if self.error else error_low)


def profile(cfg, coarsest, f, exact, components):
    """The Profile of the data on the family's coarsest Domain: f (UFL, the load's density), and with `exact`
    (UFL u_ex, None for a data-only scene) its interpolant's errors; `components(points)`: u_ex in numpy,
    (..., c). All candidate rules at once, by chunks of cells (PROFILE_VALUES: the peak memory stays a chunk's)."""
    msh = coarsest.mesh
    V = element.space(msh, cfg.element.degree)
    cell_type = basix.cell.string_to_type(msh.topology.cell_name())
    rules = {q: basix.make_quadrature(cell_type, q) for q in CANDIDATES + (REFERENCE_DEGREE,)}
    X = np.concatenate([X for X, _ in rules.values()])
    parts = [ufl.as_vector([f]) if not ufl.shape(f) else f]
    if exact is not None:
        u = ufl.as_vector([exact]) if not ufl.shape(exact) else exact
        parts += [u, ufl.as_vector([ufl.grad(u)[i, j] for i in range(len(u)) for j in range(msh.geometry.dim)])]
    expression = fem.Expression(ufl.as_vector([c for p in parts for c in p]), X)
    owned = msh.topology.index_map(msh.topology.dim).size_local
    load_change, load_scale = {q: 0.0 for q in rules}, 0.0
    sums = {q: np.zeros(2) for q in rules}
    chunk = max(1, PROFILE_VALUES // (len(X) * sum(len(p) for p in parts)))
    for start in range(0, owned, chunk):
        cells = np.arange(start, min(start + chunk, owned), dtype=np.int32)
        found = _chunk(V, rules, expression.eval(cells).reshape(len(cells), len(X), -1), [len(p) for p in parts],
                       cells, components if exact is not None else None)
        ref_load = found[REFERENCE_DEGREE][0]
        load_scale = max(load_scale, float(np.abs(ref_load).max(initial=0.0)))
        for q, (load, errors) in found.items():
            load_change[q] = max(load_change[q], float(np.abs(load - ref_load).max(initial=0.0)))
            sums[q] += errors
    comm = msh.comm
    scale = max(comm.allreduce(load_scale, op=MPI.MAX), 1e-300)
    sums = {q: comm.allreduce(s, op=MPI.SUM) for q, s in sums.items()}
    ref = sums[REFERENCE_DEGREE]
    error = {q: float(np.max(np.abs(sums[q] - ref) / np.where(ref > 0, ref, np.inf))) for q in CANDIDATES}
    return Profile(coarsest.h, {q: comm.allreduce(load_change[q], op=MPI.MAX) / scale for q in CANDIDATES},
                   error if exact is not None else {}, cfg.element.degree)


def _chunk(V, rules, values, sizes, cells, components):
    """{q: (the cells' load vectors (cells, dofs, f), their error integrals (L2², H1²) or zeros)} of one chunk
    of cells on affine simplices: values (cells, points, f | u_ex | ∇u_ex) at every rule's points in turn."""
    msh = V.mesh
    tdim = msh.topology.dim
    vertices = msh.geometry.x[msh.geometry.dofmap.array.reshape(-1, tdim + 1)[cells]][..., :tdim]
    J = np.swapaxes(vertices[:, 1:] - vertices[:, :1], 1, 2)  # (cells, d, d): x = x0 + J X
    det = np.abs(np.linalg.det(J))
    X = np.concatenate([X for X, _ in rules.values()])
    tab = V.element.basix_element.tabulate(1, X)[..., 0]  # (1 + d, points, dofs)
    if components is not None:
        cell_dofs = V.dofmap.list.array.reshape(-1, V.dofmap.dof_layout.num_dofs)[cells]
        nodal = components(V.tabulate_dof_coordinates()[cell_dofs])  # (cells, dofs, c)
        inverse = np.linalg.inv(J)
    f_end, u_end = sizes[0], sizes[0] + (sizes[1] if len(sizes) > 1 else 0)
    start, found = 0, {}
    for q, (Xq, wq) in rules.items():
        at = slice(start, start + len(Xq))
        start += len(Xq)
        load = np.einsum("cpf,pk,p,c->ckf", values[:, at, :f_end], tab[0, at], wq, det, optimize=True)
        errors = np.zeros(2)
        if components is not None:
            e = np.einsum("pk,ckf->cpf", tab[0, at], nodal, optimize=True) - values[:, at, f_end:u_end]
            reference = np.einsum("jpk,ckf->cpfj", tab[1:, at], nodal, optimize=True)  # ∇ in reference coordinates
            grad_e = np.einsum("cji,cpfj->cpfi", inverse, reference, optimize=True).reshape(len(cells), len(Xq), -1) \
                - values[:, at, u_end:]
            errors = np.array([np.einsum("cpf,p,c->", e**2, wq, det, optimize=True),
                               np.einsum("cpg,p,c->", grad_e**2, wq, det, optimize=True)])
        found[q] = (load, errors)
    return found
