"""Error norms against the exact solution, integrated with raised quadrature and MPI-reduced."""
import numpy as np
import ufl
from mpi4py import MPI

from dolfinx import fem

from . import element, kinked




def integrate(expr, measure):
    """∫ expr over `measure`, summed over ranks."""
    comm = measure.ufl_domain().ufl_cargo().comm
    return comm.allreduce(fem.assemble_scalar(fem.form(expr * measure)), op=MPI.SUM)


def errors(u_h, u_exact, h, degree=None):
    """{'L2': ||u − u_h||_{L2(Ω)}, 'H1': |u − u_h|_{H1(Ω)} (the seminorm, as in the paper)}, of a scalar or
    vector u_h; the quadrature `degree` the data need (posed.Profile), else by h, the mesh's size (Domain.h),
    and u_h's degree (element.error_degree)."""
    msh = u_h.function_space.mesh
    degree = error_degree(u_h.function_space, h) if degree is None else degree
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": degree})
    e = u_h - u_exact
    l2, h1 = integrate_together(msh, [ufl.inner(e, e), ufl.inner(ufl.grad(e), ufl.grad(e))], dx)
    return {"L2": np.sqrt(abs(l2)), "H1": np.sqrt(abs(h1))}


def integrate_together(msh, exprs, dx):
    """[∫ expr dx for expr in exprs], summed over ranks, in one pass over the cells of msh: the integrands
    share their quadrature points (u_ex and u_h are evaluated once, not once per norm). Each cell's
    integrals land in a DG0 vector, one component per expression, summed as assemble_scalar sums."""
    V0 = fem.VectorFunctionSpace(msh, ("DG", 0), dim=len(exprs))
    w = ufl.TestFunction(V0)
    per_cell = fem.assemble_vector(fem.form(sum(expr * w[i] for i, expr in enumerate(exprs)) * dx))
    local = per_cell.array.reshape(-1, len(exprs)).sum(axis=0)
    return msh.comm.allreduce(local, op=MPI.SUM)


def error_degree(V, h):
    """The quadrature degree of the error integrals of a function in V on a mesh of size h."""
    return element.error_degree(element.degree_of(V), h, V.mesh.topology.dim)


def product_degree(V):
    """The quadrature degree exact for ∫ u v and ∫ ∇u·∇v of u, v in V."""
    return element.product_degree(element.degree_of(V))


def difference_norms(u_h, u):
    """{'L2': ||u - u_h||_{L2}, 'H1': |u - u_h|_{H1}} for two functions of one space (exact quadrature)."""
    V = u.function_space
    dx = ufl.Measure("dx", domain=V.mesh, metadata={"quadrature_degree": product_degree(V)})
    e = u - u_h
    return {"L2": np.sqrt(abs(integrate(ufl.inner(e, e), dx))),
            "H1": np.sqrt(abs(integrate(ufl.inner(ufl.grad(e), ufl.grad(e)), dx)))}


def model_differences(u_eps, u_S, ds_c, gamma_c_dofs):
    """The model error of an ε-sweep: ||u_{ε,h} − u_{S,h}|| in L2(Ω), H1 (seminorm) and L2(Γ_C) (`ds_c`
    exact for products of the two), and the largest penetration max_Γc [u_{ε,h}]_+ (a nodal max for P1)."""
    found = difference_norms(u_eps, u_S)
    found["L2_gamma_c"] = np.sqrt(abs(integrate((u_eps - u_S) ** 2, ds_c)))
    found["penetration"] = penetration(u_eps, gamma_c_dofs)
    return found


# --- Γ_C: the contact-boundary terms of Lemma 3.1 and Corollary 3.2, and what a user quotes ---------

def contact_errors(comm, points, w_h, w, eps, alpha, h1):
    """Γ_C errors of w_h against w on the rank's owned Γ_C facets (points (facets, k, 3)), given the H1
    seminorm h1: L2_gc = ||w - w_h||_{L2(Γ_C)}, pos_gc = ||[w]_+ - [w_h]_+||_{L^{alpha+1}(Γ_C)}, its scaled
    form pos_gc^{(alpha+1)/2} (Cor. 3.2 ii) and energy_err = (h1^2 + pos_gc^{alpha+1}/eps)^{1/2} (Lemma 3.1).
    w_h and w are facet dof values (facets, k) of a discrete function or an expression w(facets, x); every
    facet is cut at the zeros of w_h, w and w - w_h (kinked.on_facets: the integrands are smooth between),
    those of an expression searched as finely as the degree of w_h asks (kinked.SEARCH)."""
    search = kinked.SEARCH[1 if np.shape(w_h)[1] == points.shape[1] else 2]
    u_h, u = on_facets(w_h, search), on_facets(w, search)

    def integrand(facets, lam, x):
        a, b = u[0](facets, lam, x), u_h[0](facets, lam, x)
        return np.stack(((a - b) ** 2, np.abs(np.maximum(a, 0) - np.maximum(b, 0)) ** (alpha + 1)), axis=-1)

    def difference(facets, lam, x):
        return u[0](facets, lam, x) - u_h[0](facets, lam, x)
    kinks = [u_h, u, (difference, None if u_h[1] is None and u[1] is None else search)]
    local = kinked.on_facets(points, integrand, kinks).sum(axis=0) if len(points) else np.zeros(2)
    squared, pos_power = comm.allreduce(local, op=MPI.SUM)
    pos_gc = pos_power ** (1 / (alpha + 1))
    return {"L2_gc": np.sqrt(squared), "pos_gc": pos_gc, "pos_gc_scaled": pos_gc ** ((alpha + 1) / 2),
            "energy_err": np.sqrt(h1**2 + pos_power / eps)}


def on_facets(w, search=None):
    """(w(facets, lam, x), search) as kinked.on_facets takes a kink: of facet dof values (a P1 trace, or P2:
    vertices, then the midpoints of the edges, as contact_facet_dofs orders them; search None: a polynomial)
    or of an expression w(facets, x), whose zeros are found by `search`."""
    if callable(w):
        return (lambda facets, lam, x: np.broadcast_to(w(facets, x), x.shape[:-1])), search
    values = np.asarray(w)

    def trace(facets, lam, x):
        if lam.shape[-1] == values.shape[1]:  # P1: the barycentric coordinates are the basis
            return np.einsum("pqk,pk->pq", lam, values[facets])
        return np.einsum("pqk,pk->pq", p2_basis(lam), values[facets])
    return trace, None


def p2_basis(lam):
    """The P2 basis at barycentric coordinates lam (..., n+1) of a segment or a triangle: its vertices', then
    its edges' midpoints' (a triangle's edge k opposite vertex k, as a tetrahedron's facet lists them)."""
    vertices = [lam[..., i] * (2 * lam[..., i] - 1) for i in range(lam.shape[-1])]
    edges = [(0, 1)] if lam.shape[-1] == 2 else [(1, 2), (0, 2), (0, 1)]
    return np.stack(vertices + [4 * lam[..., i] * lam[..., j] for i, j in edges], axis=-1)


P2_VERTICES = {3: 2, 6: 3}  # P2 dofs on a facet -> its vertices: a segment's, a triangle's


def vertices(points, degree):
    """The facets' vertices among their dof points (facets, k, 3), vertices first (contact_facet_dofs)."""
    return points if degree == 1 else points[:, :P2_VERTICES[points.shape[1]]]


def energy(u_h, f, g, eps, dx, ds_c, penalty):
    """The potential whose derivative is the weak form (10) with data g:
    J(u_h) = ½∫|∇u_h|² + 1/(eps(alpha+1)) ∫_Γc [u_h]_+^{alpha+1} - ∫ f u_h - (1/eps) ∫_Γc g u_h, the
    kinked term given as `penalty` = ∫_Γc [u_h]_+^{alpha+1}/(alpha+1) (exact for P1: contact.positive_power)."""
    bulk = integrate(ufl.inner(ufl.grad(u_h), ufl.grad(u_h)) / 2 - f * u_h, dx)
    data = 0.0 if isinstance(g, (int, float)) and g == 0 else integrate(g * u_h, ds_c)
    return bulk + (penalty - data) / eps


def penetration(u_h, contact_dofs):
    """The largest penetration max_{Γ_C} [u_h]_+: for P1 attained at a vertex of Γ_C (contact_dofs, any
    shape); for P2 the maximum of each Γ_C facet's quadratic (contact_dofs from contact_facet_dofs)."""
    values = u_h.x.array[contact_dofs]
    if element.degree_of(u_h.function_space) == 2 and values.size:
        values = quadratic_max(values)
    local = float(values.max()) if values.size else 0.0
    return max(u_h.function_space.mesh.comm.allreduce(local, op=MPI.MAX), 0.0)


def vertex_penetration(comm, values, degree=1):
    """max [w_h]_+ over the Γ_C facets' dof values (facets, k) of every rank: exact for P1 (a vertex's) and
    for P2 (each facet's quadratic's maximum)."""
    if degree == 2 and values.size:
        values = quadratic_max(values)
    local = float(values.max()) if values.size else 0.0
    return max(comm.allreduce(local, op=MPI.MAX), 0.0)


def vertex_contact_measure(comm, values, points, degree=1):
    """|{w_h > 0} ∩ Γ_C| from the dof values (facets, k) and points (facets, k, 3) of the rank's owned Γ_C
    facets: exact for P1 (positive_fraction) and for P2 (p2_positive_measure)."""
    if not len(values):
        return comm.allreduce(0.0, op=MPI.SUM)
    if degree == 2:
        return comm.allreduce(float(np.sum(p2_positive_measure(values, points))), op=MPI.SUM)
    return comm.allreduce(float(np.sum(facet_sizes(points) * positive_fraction(values))), op=MPI.SUM)


def contact_measure(u_h, facet_dofs, facet_points):
    """|{u_h > 0} ∩ Γ_C|, exact for P1 and P2: on each Γ_C facet (its dofs and their points, vertices first)
    the positive part of a linear function covers a fraction of the facet known in closed form, that of a
    quadratic p2_positive_measure."""
    return vertex_contact_measure(u_h.function_space.mesh.comm, u_h.x.array[facet_dofs], facet_points,
                                  element.degree_of(u_h.function_space))


def p2_positive_measure(values, points):
    """|{w > 0}| on each P2 facet from its dof values (facets, k) and points (facets, k, 3): on a segment
    in closed form, on a triangle by kinked.on_facets (cut at the conic w = 0 and where it is tangent to the
    lines of the rule: the length along each line in closed form, smooth between the cuts)."""
    if values.shape[1] == 3:
        return facet_sizes(points[:, :2]) * quadratic_positive_fraction(values)
    trace = on_facets(values)
    return kinked.on_facets(points[:, :3], lambda *a: (trace[0](*a) > 0).astype(float), [trace])


def quadratic(values):
    """(a, B, C): p(t) = a + B t + C t² on [0, 1] through the values (p(0), p(1), p(1/2)), shape (n, 3)."""
    a, b, m = values[:, 0], values[:, 1], values[:, 2]
    return a, 4 * m - 3 * a - b, 2 * a + 2 * b - 4 * m


def quadratic_max(values):
    """max of each P2 facet's quadratic from its dof values: segments (facets, 3), triangles (facets, 6)."""
    return segment_max(values) if values.shape[1] == 3 else triangle_max(values)


def triangle_max(values):
    """max over each triangle of its quadratic (values at kinked.P2_NODES): the largest of its edges' maxima
    and of its value at a stationary point inside, where ∇w = 0 (a 2 × 2 system in (a, b))."""
    v0, v1, v2, m0, m1, m2 = values.T
    edges = [segment_max(np.stack(e, axis=1)) for e in ((v1, v2, m0), (v0, v2, m1), (v0, v1, m2))]
    c0, c1, c2, c3, c4, c5 = kinked.triangle_coefficients(values)
    det = 4 * c3 * c5 - c4**2
    with np.errstate(divide="ignore", invalid="ignore"):
        a, b = (c4 * c2 - 2 * c5 * c1) / det, (c4 * c1 - 2 * c3 * c2) / det
    inside = (det != 0) & (a >= 0) & (b >= 0) & (a + b <= 1)
    stationary = np.where(inside, c0 + c1 * a + c2 * b + c3 * a**2 + c4 * a * b + c5 * b**2, -np.inf)
    return np.max(np.stack(edges + [stationary]), axis=0)


def segment_max(values):
    """max over [0, 1] of each segment's quadratic: its end values, or its vertex inside when concave."""
    a, B, C = quadratic(values)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(C < 0, -B / (2 * C), 0.0)
    t = np.clip(t, 0.0, 1.0)
    return np.maximum(values[:, :2].max(axis=1), a + B * t + C * t**2)


def quadratic_positive_fraction(values):
    """Fraction of [0, 1] where each segment's quadratic is > 0: its sign on the pieces between its zeros."""
    a, B, C = quadratic(values)
    with np.errstate(divide="ignore", invalid="ignore"):
        disc = np.sqrt(np.where(C != 0, B**2 - 4 * a * C, np.nan))
        roots = np.stack((np.where(C != 0, (-B - disc) / (2 * C), -a / B),
                          np.where(C != 0, (-B + disc) / (2 * C), np.nan)), axis=1)
    roots = np.where(np.isfinite(roots), np.clip(roots, 0.0, 1.0), 1.0)
    breaks = np.sort(np.concatenate((np.zeros((len(a), 1)), roots, np.ones((len(a), 1))), axis=1), axis=1)
    middle = (breaks[:, 1:] + breaks[:, :-1]) / 2
    positive = a[:, None] + B[:, None] * middle + C[:, None] * middle**2 > 0
    return np.sum(np.diff(breaks, axis=1) * positive, axis=1)


def facet_sizes(points):
    """Lengths (segments) or areas (triangles) of facets given as (n, vertices, 3) points."""
    if points.shape[1] == 2:
        return np.linalg.norm(points[:, 1] - points[:, 0], axis=1)
    return np.linalg.norm(np.cross(points[:, 1] - points[:, 0], points[:, 2] - points[:, 0]), axis=1) / 2


def positive_fraction(values):
    """Fraction of a simplex where the linear function with these vertex values is > 0."""
    v = -np.sort(-values, axis=1)  # descending: v[:, 0] >= v[:, 1] >= ...
    top, low = v[:, 0], v[:, -1]
    with np.errstate(divide="ignore", invalid="ignore"):
        if v.shape[1] == 2:  # segment: the zero splits it at top/(top - low)
            part = top / (top - low)
        else:  # triangle: one vertex above zero cuts a corner triangle, two leave one cut off below
            mid = v[:, 1]
            part = np.where(mid > 0, 1 - low**2 / ((top - low) * (mid - low)),
                            top**2 / ((top - mid) * (top - low)))
    return np.where(low > 0, 1.0, np.where(top <= 0, 0.0, part))


def contact_facet_dofs(V, facet_tags, marker):
    """(dofs, points): for each facet tagged `marker` and owned by this rank, its dofs and their
    coordinates, shape (facets, k) and (facets, k, 3): P1 the vertices, P2 the vertices then the edge's."""
    msh = V.mesh
    tdim = msh.topology.dim
    facets = facet_tags.indices[facet_tags.values == marker]
    facets = facets[facets < msh.topology.index_map(tdim - 1).size_local]  # owned: counted once
    if element.degree_of(V) > 1:
        dofs = facet_closure_dofs(V, facets)
        return dofs, V.tabulate_dof_coordinates()[dofs]
    msh.topology.create_connectivity(tdim - 1, 0)
    f2v = msh.topology.connectivity(tdim - 1, 0).array.reshape(-1, tdim)  # simplices: tdim vertices
    dofs = vertex_to_dof(V)[f2v[facets]]
    return dofs, V.tabulate_dof_coordinates()[dofs]


def facet_closure_dofs(V, facets):
    """The dofs on the closure of each facet (its vertices' first), read from one cell holding it."""
    msh = V.mesh
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    msh.topology.create_connectivity(tdim, tdim - 1)
    f2c, c2f = msh.topology.connectivity(tdim - 1, tdim), msh.topology.connectivity(tdim, tdim - 1)
    cells = f2c.array[f2c.offsets[facets]]
    local = np.argmax(c2f.array.reshape(-1, tdim + 1)[cells] == facets[:, None], axis=1)
    closure = np.array([V.dofmap.dof_layout.entity_closure_dofs(tdim - 1, i) for i in range(tdim + 1)])
    cell_dofs = V.dofmap.list.array.reshape(-1, V.dofmap.dof_layout.num_dofs)
    return cell_dofs[cells[:, None], closure[local]]


def vertex_to_dof(V):
    """The P1 dof at each (local) vertex: a cell lists its vertices and its P1 dofs in the same order."""
    msh = V.mesh
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim, 0)
    cell_vertices = msh.topology.connectivity(tdim, 0).array.reshape(-1, tdim + 1)
    cell_dofs = V.dofmap.list.array.reshape(-1, tdim + 1)
    index_map = msh.topology.index_map(0)
    v2d = np.full(index_map.size_local + index_map.num_ghosts, -1, dtype=np.int32)
    v2d[cell_vertices] = cell_dofs
    return v2d
