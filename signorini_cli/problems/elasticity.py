"""Linear elasticity, a problem of its own (space, operator, data, Γ_C side w = u·n − g0, errors); with the penalty
method it is the vector analogue of the scalar compliance model (docs/elasticity.md).

    −div σ(u) = f in Ω,   u = u_D on Γ_D,   ε σ_n(u) + [u·n − g0]_+^α = ĝ_n,  σ_t(u) = ĝ_t on Γ_C,

σ(u) = 2μ ε(u) + λ (div u) I (plane strain in 2-D); `eps` is always the compliance parameter ε, `strain`
the symmetric gradient. With the manufactured data the two Γ_C conditions add up to the traction σ(u)n:

    ∫ σ(u_h):ε(v) + (1/ε)∫_Γc [w_h]_+^α (v·n)
        = ∫ f·v + ∫_Γc σ(u_ex)n·v + (1/ε)∫_Γc [w_ex]_+^α (v·n),

w = u·n − g0. On a flat Γ_C facet w_h is linear (P1, g0 affine) or quadratic (P2, g0 at most quadratic),
so contact.ContactTerm integrates the penalty exactly (P2: each facet cut at the zeros of the quadratic, as
for the scalar problem), and the kinked data [w_ex]_+^α by its adaptive rules when n is one vector on all
of Γ_C."""
from contextlib import ExitStack

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

from dolfinx import cpp, fem, la

from ..config import expressions
from ..meshing.meshes import CONTACT
from . import compliance, contact, element, forms, measure
from .forms import QUADRATURE_DEGREE


def space(cfg, msh):
    """Vector Lagrange of the configured degree (P1 or P2), d components."""
    return element.space(msh, cfg.element.degree, shape=(msh.geometry.dim,))


def lame(material):
    """(μ, λ) from E and ν; in 2-D plane strain."""
    E, nu = material.E, material.nu
    return E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))


def strain(u):
    return ufl.sym(ufl.grad(u))


def sigma(u, mu, lmbda):
    return 2 * mu * strain(u) + lmbda * ufl.tr(strain(u)) * ufl.Identity(len(u))


def exact_solution(cfg, msh, eps):
    """u_ex as a UFL vector (a constant component gets 0·x, so that the vector lives on the mesh)."""
    x = ufl.SpatialCoordinate(msh)
    variables = dict(zip(("x", "y", "z"), x), eps=eps)
    return ufl.as_vector([c(variables, expressions.ufl_functions()) + 0 * x[0] for c in cfg.problem.exact])


def gap(cfg, x, functions):
    """g0 at the coordinates x (UFL or numpy), 0 by default."""
    if cfg.problem.gap is None:
        return 0 * x[0]
    return cfg.problem.gap(dict(zip(("x", "y", "z"), x)), functions) + 0 * x[0]


class Trace:
    """The elastic solution on Γ_C, what the measures read: w = u·n − g0 of u_h and u_ex (UFL; w_ex also in
    numpy, `exact`), a(e, e) of an error e (`energy`, UFL), and from the facet dof values of w_h (`term`: a
    ContactTerm that reads them) the penetration, the contact set and ∫[w_h]_+^beta, exact for P1 and P2."""

    def __init__(self, cfg, w_h, w_exact, u_exact, energy, term, domain):
        self.cfg, self.w_h, self.w_exact, self.u_exact = cfg, w_h, w_exact, u_exact
        self.energy, self.term, self.domain = energy, term, domain

    def dof_values(self):
        return self.term.values(self.term.u_h.x.array)

    def exact(self, eps_value):
        """w_ex(facets, x) = u_ex(x)·n_F − g0(x) at points x (P, q, 3) of the rank's owned Γ_C facets F."""
        normal = self.term.normal

        def evaluate(facets, x):
            coords = np.moveaxis(x, -1, 0)[:normal.shape[1]]
            variables = dict(zip(("x", "y", "z"), coords), eps=eps_value)
            functions = expressions.numpy_functions()
            u = [np.broadcast_to(c(variables, functions), coords[0].shape) for c in self.cfg.problem.exact]
            n = normal[facets]  # (P, d)
            return sum(n[:, k, None] * u_k for k, u_k in enumerate(u)) - gap(self.cfg, coords, functions)
        return evaluate

    def contact_variable(self, level):
        """(points, w_h, w_ex, seminorm) the Γ_C errors read: the facets' vertices, w_h's facet dof values (as
        the solve's contact term has them), w_ex(facets, x) and the energy seminorm a(e, e)^(1/2) of the error."""
        u_h, msh = self.term.u_h, self.domain.mesh
        quadrature = self.domain.quadrature
        degree = quadrature[1] if quadrature else measure.error_degree(u_h.function_space, level.h)
        dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": degree})
        a_ee = measure.integrate(self.energy(self.u_exact - u_h), dx)
        vertices = self.term.points[:, :msh.topology.dim]
        return vertices, self.dof_values(), self.exact(level.eps), abs(a_ee) ** 0.5

    def penetration(self):
        return measure.vertex_penetration(self.domain.mesh.comm, self.dof_values(), self.cfg.element.degree)

    def contact_measure(self):
        return measure.vertex_contact_measure(self.domain.mesh.comm, self.dof_values(), self.term.points,
                                              self.cfg.element.degree)

    def positive_power(self, beta):
        """∫_Γc [w_h]_+^beta from the facet dof values, exact (contact.positive_power)."""
        return contact.positive_power(self.domain.mesh.comm, self.dof_values(), self.term.points, beta,
                                      self.cfg.element.degree)

    def potential(self, eps, contact_energy):
        """No potential is measured for elasticity."""
        return None


def boundary(cfg, domain, u_h, eps):
    """Elasticity's side of Γ_C (forms.Boundary): w = u·n − g0, v_n = v·n, the flux σ_n(u) = σ(u)n·n, with
    a(u, v) = ∫ σ(u):ε(v), the load ∫ f·v and the traction ∫_Γc σ(u_ex)n·v of a manufactured u_ex."""
    msh = domain.mesh
    V = u_h.function_space
    v = ufl.TestFunction(V)
    mu, lmbda = lame(cfg.material)
    rule = cfg.contact_quadrature
    data_degree = domain.quadrature[0] if domain.quadrature else QUADRATURE_DEGREE  # as the data need (posed)
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": data_degree})
    ds_c = domain.ds_c(rule if isinstance(rule, int) else data_degree)
    n = ufl.as_vector(cfg.problem.normal) if cfg.problem.normal is not None else ufl.FacetNormal(msh)
    x = ufl.SpatialCoordinate(msh)
    u_ex = exact_solution(cfg, msh, eps) if cfg.problem.exact is not None else None
    g0 = gap(cfg, x, expressions.ufl_functions())
    w_h = ufl.dot(u_h, n) - g0
    w_ex = ufl.dot(u_ex, n) - g0 if u_ex is not None else None
    traction = None if u_ex is None else ufl.dot(ufl.dot(sigma(u_ex, mu, lmbda), n), v) * ds_c

    def term(penalty, kinked):
        return contact_term(cfg, domain, u_h, eps, penalty, kinked)

    stiffness = ufl.inner(sigma(u_h, mu, lmbda), strain(v)) * ufl.dx(domain=msh)  # UFL's degree 2(k−1): exact
    energy = lambda e: ufl.inner(sigma(e, mu, lmbda), strain(e))  # noqa: E731
    measuring = contact_term(cfg, domain, u_h, eps, False, False, measuring=True)
    trace = Trace(cfg, w_h, w_ex, u_ex, energy, measuring, domain)
    return forms.Boundary(u_h, w_h, w_ex, ufl.dot(v, n), lambda u: ufl.dot(ufl.dot(sigma(u, mu, lmbda), n), n),
                          traction, 0, ds_c, fem.Constant(msh, domain.h), term, stiffness,
                          load_form(u_ex, v, mu, lmbda, dx), u_ex, trace, domain, rigid_motions(V), gap=trace)


def load_form(u_ex, v, mu, lmbda, dx):
    """∫ f·v with f = −div σ(u_ex); the physical problem (no u_ex): f = 0."""
    if u_ex is None:
        return ufl.inner(fem.Constant(v.ufl_function_space().mesh, np.zeros(len(v))), v) * dx
    return ufl.dot(-ufl.div(sigma(u_ex, mu, lmbda)), v) * dx


def contact_term(cfg, domain, u_h, eps, penalty=False, kinked=False, measuring=False):
    """The Γ_C terms beside UFL on w = u·n − g0 (contact_quadrature exact or vertex; None for a Gauss rule
    unless `measuring`: then a term that only reads w_h's vertex values). The kinked data term joins it
    when n is one vector on all of Γ_C: then w_ex is a function of x alone for the adaptive rules."""
    rule = cfg.contact_quadrature
    if isinstance(rule, int) and not measuring:
        return None
    facets = owned_contact_facets(domain)
    normal = facet_normals(domain.mesh, facets)
    if cfg.problem.normal is not None:
        normal = np.broadcast_to(np.array(cfg.problem.normal), normal.shape)
    n_c = common_normal(domain.mesh.comm, normal)
    u_fn = numpy_gap(cfg, n_c) if kinked and n_c is not None and not measuring else None
    g0 = lambda points: gap(cfg, np.moveaxis(points, -1, 0), expressions.numpy_functions())  # noqa: E731
    return contact.ContactTerm(u_h, domain.facet_tags, CONTACT, cfg.alpha, eps, "exact" if measuring else rule,
                               penalty and not measuring, u_fn, normal=np.ascontiguousarray(normal), gap=g0)


def owned_contact_facets(domain):
    """The rank's owned Γ_C facets, in the order of measure.contact_facet_dofs."""
    msh = domain.mesh
    facets = domain.facets(CONTACT)
    return facets[facets < msh.topology.index_map(msh.topology.dim - 1).size_local]


def facet_normals(msh, facets):
    """The outward unit normal of each (flat) facet, (facets, d): orthogonal to its edges, pointing away
    from the centroid of its cell."""
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    f2c = msh.topology.connectivity(tdim - 1, tdim)
    d = msh.geometry.dim
    if not len(facets):
        return np.zeros((0, d))
    facet_x = msh.geometry.x[cpp.mesh.entities_to_geometry(msh._mesh, tdim - 1, facets, False)][..., :d]
    cells = np.array([f2c.links(f)[0] for f in facets], dtype=np.int32)
    cell_x = msh.geometry.x[cpp.mesh.entities_to_geometry(msh._mesh, tdim, cells, False)][..., :d]
    edges = facet_x[:, 1:] - facet_x[:, :1]
    if d == 2:
        n = np.stack((edges[:, 0, 1], -edges[:, 0, 0]), axis=1)
    else:
        n = np.cross(edges[:, 0], edges[:, 1])
    outward = np.einsum("fk,fk->f", n, facet_x.mean(axis=1) - cell_x.mean(axis=1))
    n *= np.sign(outward)[:, None]
    return n / np.linalg.norm(n, axis=1)[:, None]


def common_normal(comm, normal, tol=1e-12):
    """The normal shared by every Γ_C facet on every rank (a flat Γ_C), or None."""
    firsts = [m for m in comm.allgather(normal[0] if len(normal) else None) if m is not None]
    if not firsts:
        return None
    flat = bool(np.abs(normal - firsts[0]).max(initial=0.0) <= tol)
    return firsts[0] if comm.allreduce(flat, op=MPI.LAND) else None


def numpy_gap(cfg, n):
    """w_ex(points, eps) = u_ex·n − g0 in numpy, points (..., 3): the kinked data term's integrand."""
    dim = len(n)

    def evaluate(points, eps_value):
        coords = np.moveaxis(points, -1, 0)[:dim]
        variables = dict(zip(("x", "y", "z"), coords), eps=eps_value)
        functions = expressions.numpy_functions()
        u = [np.broadcast_to(c(variables, functions), coords[0].shape) for c in cfg.problem.exact]
        return sum(n_k * u_k for n_k, u_k in zip(n, u)) - gap(cfg, coords, functions)
    return evaluate


def dirichlet_condition(V, domain, u_exact):
    """u = u_ex on Γ_D."""
    return compliance.dirichlet_condition(V, domain, u_exact)


def errors(u_h, u_exact, h, degree=None):
    """{'L2': ||u − u_h||_{L2(Ω)}, 'H1': |u − u_h|_{H1(Ω)} (seminorm)} of the vector error (`degree` as
    compliance.errors')."""
    return measure.errors(u_h, u_exact, h, degree)


def rigid_motions(V):
    """The near-nullspace of elasticity for AMG: d translations and d(d−1)/2 rotations (3 in 2-D, 6 in 3-D),
    orthonormalised; the rotation about the axis i×j is (−x_j e_i + x_i e_j)."""
    d = V.mesh.geometry.dim
    rotations = [(0, 1)] if d == 2 else [(0, 1), (0, 2), (1, 2)]
    basis = [la.create_petsc_vector(V.dofmap.index_map, V.dofmap.index_map_bs) for _ in range(d + len(rotations))]
    x = V.tabulate_dof_coordinates()
    with ExitStack() as stack:
        b = [np.asarray(stack.enter_context(vec.localForm())).reshape(-1, d) for vec in basis]
        for i in range(d):
            b[i][:, i] = 1.0
        for k, (i, j) in enumerate(rotations):
            b[d + k][:, i], b[d + k][:, j] = -x[:, j], x[:, i]
    la.orthonormalize(basis)
    return PETSc.NullSpace().create(vectors=basis, comm=V.mesh.comm)  # not PETSc's default, COMM_WORLD


# --- fields for ParaView: stress, von Mises, contact pressure ------------------------------------------

def stress(cfg, u):
    """σ(u) (UFL) with the config's material."""
    mu, lmbda = lame(cfg.material)
    return sigma(u, mu, lmbda)


def von_mises(cfg, u):
    """(3/2 s:s)^(1/2) of the deviator s of the 3×3 stress; in 2-D plane strain σ_zz = λ div u."""
    mu, lmbda = lame(cfg.material)
    s = sigma(u, mu, lmbda)
    if len(u) == 2:
        s = ufl.as_matrix([[s[0, 0], s[0, 1], 0], [s[1, 0], s[1, 1], 0], [0, 0, lmbda * ufl.div(u)]])
    dev = ufl.dev(s)
    return ufl.sqrt(1.5 * ufl.inner(dev, dev))


def numpy_exact(cfg):
    """u_ex(points, eps) in numpy, points (..., 3) -> (..., d)."""
    def evaluate(points, eps_value):
        coords = np.moveaxis(points, -1, 0)
        variables = dict(zip(("x", "y", "z"), coords), eps=eps_value)
        functions = expressions.numpy_functions()
        return np.stack([np.broadcast_to(c(variables, functions), coords[0].shape) for c in cfg.problem.exact], -1)
    return evaluate


def pressure_values(cfg, term, eps_value, u_exact=False):
    """(1/ε)[w]_+^α at the Γ_C facets' vertices (facets, d): of w_h = u_h·n − g0, or of w_ex with `u_exact`
    (the compliance law's pressure σ_n = −(1/ε)[w]_+^α without data, the manufactured one's ĝ_n aside)."""
    if u_exact:
        u = numpy_exact(cfg)(term.points, eps_value)
        w = np.einsum("fvk,fk->fv", u, term.normal) - term.gap
    else:
        w = term.values(term.u_h.x.array)
    return np.maximum(w, 0.0) ** cfg.alpha / eps_value


def on_vertices(term, values):
    """(sums, counts): `values` (facets, vertices) at the Γ_C facets' vertices summed per vertex, and how many
    facets each vertex has, as local arrays of the scalar P1 space (ghosts included, owned facets summed across
    ranks): the space and its arrays for fields and nodal pressures."""
    from dolfinx.cpp.la import ScatterMode
    Q, blocks = term.u_h.function_space.sub(0).collapse()
    scalar_of = np.empty(len(term.u_h.x.array) // term.bs, dtype=np.int32)
    scalar_of[np.asarray(blocks) // term.bs] = np.arange(len(blocks))
    sums, counts = fem.Function(Q), fem.Function(Q)
    np.add.at(sums.x.array, scalar_of[term.dofs], values)
    np.add.at(counts.x.array, scalar_of[term.dofs], 1.0)
    for f in (sums, counts):
        f.x.scatter_reverse(ScatterMode.add)
        f.x.scatter_forward()
    return sums, counts
