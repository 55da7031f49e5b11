"""Error norms against the exact solution, integrated with raised quadrature and MPI-reduced."""
import numpy as np
import ufl
from mpi4py import MPI

from dolfinx import fem


ERROR_DEGREE = 8  # quadrature for u_h − u_ex: P1 error of a smooth u_ex, well above the rates' needs
P1_DEGREE = 2  # ∫ of products of two P1 functions or of their gradients: degree 2 is exact
# Fine levels (h <= FINE_H) take degree 6: 12 points per triangle instead of 16, 24 per tetrahedron instead
# of 45. Against degree 12 on the bench problems (u_ex = sin(2 pi x)(1-y)^2, sin(2 pi x) sin(pi y)(1-z)^2)
# it moves L2 and H1 by at most 1.6e-11 relative in 2-D (N = 64, h = 0.022; 3.2e-12 at N = 1024) and 6.0e-11
# in 3-D (N = 64, h = 0.027), where degree 8 moves them by up to 8.5e-13 (round-off). Coarser levels keep
# degree 8: in 3-D degree 6 moves L2 by 9.9e-10 at N = 32 (h = 0.054) and 1.6e-8 at N = 16. The threshold
# is in h, so a u_ex varying much faster than these (wavelength 1) needs finer levels for the same 1e-9.
FINE_ERROR_DEGREE, FINE_H = 6, 0.03


def integrate(expr, measure):
    """∫ expr over `measure`, summed over ranks."""
    comm = measure.ufl_domain().ufl_cargo().comm
    return comm.allreduce(fem.assemble_scalar(fem.form(expr * measure)), op=MPI.SUM)


def errors(u_h, u_exact, h):
    """{'L2': ||u − u_h||_{L2(Ω)}, 'H1': |u − u_h|_{H1(Ω)} (the seminorm, as in the paper)}; h, the mesh's
    size (Domain.h), sets the quadrature (error_degree)."""
    msh = u_h.function_space.mesh
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": error_degree(h)})
    e = u_h - u_exact
    l2, h1 = integrate_together(msh, [e**2, ufl.inner(ufl.grad(e), ufl.grad(e))], dx)
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


def error_degree(h):
    """The quadrature degree of the error integrals on a mesh of size h: FINE_ERROR_DEGREE when h <= FINE_H."""
    return FINE_ERROR_DEGREE if h <= FINE_H else ERROR_DEGREE


def difference_norms(u_h, u):
    """{'L2': ||u - u_h||_{L2}, 'H1': |u - u_h|_{H1}} for two P1 functions on one mesh (exact quadrature)."""
    dx = ufl.Measure("dx", domain=u.function_space.mesh, metadata={"quadrature_degree": P1_DEGREE})
    e = u - u_h
    return {"L2": np.sqrt(abs(integrate(e**2, dx))),
            "H1": np.sqrt(abs(integrate(ufl.inner(ufl.grad(e), ufl.grad(e)), dx)))}


def model_differences(u_eps, u_S, ds_c, gamma_c_dofs):
    """The model error of an ε-sweep: ||u_{ε,h} − u_{S,h}|| in L2(Ω), H1 (seminorm) and L2(Γ_C) (`ds_c`
    exact for P1 products), and the largest penetration max_Γc [u_{ε,h}]_+ (a nodal max for P1)."""
    found = difference_norms(u_eps, u_S)
    found["L2_gamma_c"] = np.sqrt(abs(integrate((u_eps - u_S) ** 2, ds_c)))
    found["penetration"] = penetration(u_eps, gamma_c_dofs)
    return found


# --- Γ_C: the contact-boundary terms of Lemma 3.1 and Corollary 3.2, and what a user quotes ---------

def positive(u):
    """[u]_+ in UFL."""
    return ufl.conditional(ufl.gt(u, 0), u, 0)


def contact_errors(u_h, u, eps, alpha, ds_c, h1):
    """Γ_C errors of u_h against u (exact expression or reference Function), given the H1 seminorm h1:
    L2_gc = ||u - u_h||_{L2(Γ_C)}, pos_gc = ||[u]_+ - [u_h]_+||_{L^{alpha+1}(Γ_C)}, its scaled form
    pos_gc^{(alpha+1)/2} (Cor. 3.2 ii) and energy_err = (h1^2 + pos_gc^{alpha+1}/eps)^{1/2} (Lemma 3.1)."""
    l2_gc = np.sqrt(abs(integrate((u - u_h) ** 2, ds_c)))
    pos_power = abs(integrate(abs(positive(u) - positive(u_h)) ** (alpha + 1), ds_c))
    pos_gc = pos_power ** (1 / (alpha + 1))
    return {"L2_gc": l2_gc, "pos_gc": pos_gc, "pos_gc_scaled": pos_gc ** ((alpha + 1) / 2),
            "energy_err": np.sqrt(h1**2 + pos_power / eps)}


def contact_force(u_h, eps, alpha, ds_c):
    """The total contact force (1/eps) ∫_Γc [u_h]_+^alpha (the boundary term of eq. (10) with v = 1)."""
    return integrate(positive(u_h) ** alpha, ds_c) / eps


def energy(u_h, f, g, eps, alpha, dx, ds_c):
    """The potential whose derivative is the weak form (10) with data g:
    J(u_h) = ½∫|∇u_h|² + 1/(eps(alpha+1)) ∫_Γc [u_h]_+^{alpha+1} - ∫ f u_h - (1/eps) ∫_Γc g u_h."""
    bulk = integrate(ufl.inner(ufl.grad(u_h), ufl.grad(u_h)) / 2 - f * u_h, dx)
    return bulk + integrate(positive(u_h) ** (alpha + 1) / (alpha + 1) - g * u_h, ds_c) / eps


def penetration(u_h, contact_dofs):
    """The largest penetration max_{Γ_C} [u_h]_+: for P1 attained at a vertex of Γ_C."""
    values = u_h.x.array[contact_dofs]
    local = float(values.max()) if values.size else 0.0
    return max(u_h.function_space.mesh.comm.allreduce(local, op=MPI.MAX), 0.0)


def vertex_penetration(comm, values):
    """max [w_h]_+ over the Γ_C facets' vertex values (facets, n+1) of every rank: exact for P1."""
    local = float(values.max()) if values.size else 0.0
    return max(comm.allreduce(local, op=MPI.MAX), 0.0)


def vertex_contact_measure(comm, values, points):
    """|{w_h > 0} ∩ Γ_C| from the P1 vertex values (facets, n+1) and points (facets, n+1, 3) of the rank's
    owned Γ_C facets (positive_fraction: exact for P1)."""
    local = float(np.sum(facet_sizes(points) * positive_fraction(values))) if len(values) else 0.0
    return comm.allreduce(local, op=MPI.SUM)


def contact_measure(u_h, facet_dofs, facet_points):
    """|{u_h > 0} ∩ Γ_C|, exact for P1: on each Γ_C facet (vertex dofs, vertex points) the positive
    part of a linear function covers a fraction of the facet known in closed form."""
    values = u_h.x.array[facet_dofs]
    local = float(np.sum(facet_sizes(facet_points) * positive_fraction(values))) if len(values) else 0.0
    return u_h.function_space.mesh.comm.allreduce(local, op=MPI.SUM)


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
    """(dofs, points): for each facet tagged `marker` and owned by this rank, the P1 dofs and
    coordinates of its vertices, shape (facets, vertices) and (facets, vertices, 3)."""
    msh = V.mesh
    tdim = msh.topology.dim
    facets = facet_tags.indices[facet_tags.values == marker]
    facets = facets[facets < msh.topology.index_map(tdim - 1).size_local]  # owned: counted once
    msh.topology.create_connectivity(tdim - 1, 0)
    f2v = msh.topology.connectivity(tdim - 1, 0).array.reshape(-1, tdim)  # simplices: tdim vertices
    dofs = vertex_to_dof(V)[f2v[facets]]
    return dofs, V.tabulate_dof_coordinates()[dofs]


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
