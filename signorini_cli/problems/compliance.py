"""The scalar problem −Δu = f in UFL: its space, operator, data (manufactured or given), Γ_C side and errors."""
import numpy as np

import ufl
from dolfinx import fem

from ..config import expressions
from ..meshing.meshes import CONTACT, DIRICHLET
from . import contact, element, forms, measure
from .forms import QUADRATURE_DEGREE
from .penalty import compliance


def space(cfg, msh):
    """The scalar Lagrange space of the configured degree (element.degree)."""
    return element.space(msh, cfg.element.degree)


def errors(u_h, u_exact, h, degree=None):
    """{'L2', 'H1'}: ||u_ex − u_h||_{L2(Ω)} and the seminorm |u_ex − u_h|_{H1(Ω)}, MPI-reduced (`degree`: the
    quadrature the data need, else the element's default for h)."""
    return measure.errors(u_h, u_exact, h, degree)


def exact_solution(cfg, msh, eps):
    """u_ex as UFL in the mesh's spatial coordinates, or None."""
    if cfg.problem.exact is None:
        return None
    return forms.on_mesh(cfg.problem.exact(_variables(msh, eps), expressions.ufl_functions()), msh)


def data(cfg, msh, eps, u_exact, n):
    """(f, g): from u_ex (f = -Δu_ex, g = eps ∂_n u_ex + [u_ex]_+^alpha) or from the config."""
    if u_exact is not None:
        if cfg.problem.exact_solves == "signorini":  # u_S: contact data g = 0, f and u_D only (docs/limit.md)
            return -ufl.div(ufl.grad(u_exact)), 0.0
        exact_pp = type(cfg.positive_part)()  # g uses the exact positive part: u_ex solves the exact model
        g = eps * ufl.dot(ufl.grad(u_exact), n) + compliance(u_exact, cfg.alpha, exact_pp, None, eps)
        return -ufl.div(ufl.grad(u_exact)), g
    variables, functions = _variables(msh, eps), expressions.ufl_functions()
    f = cfg.problem.f(variables, functions)
    g = cfg.problem.g(variables, functions) if cfg.problem.g is not None else 0.0
    return f, g


def boundary(cfg, domain, u_h, eps):
    """The scalar problem's side of Γ_C (forms.Boundary): w = u, v_n = v, the flux ∂_n u, with
    a(u, v) = ∫ ∇u·∇v and the load ∫ f v."""
    msh = domain.mesh
    v = ufl.TestFunction(u_h.function_space)
    rule = cfg.contact_quadrature
    data_degree = domain.quadrature[0] if domain.quadrature else QUADRATURE_DEGREE  # as the data need (posed)
    degree = rule if isinstance(rule, int) else data_degree
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": data_degree})
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=domain.facet_tags,
                       metadata={"quadrature_degree": degree})(CONTACT)
    u_exact = exact_solution(cfg, msh, eps)
    n = ufl.FacetNormal(msh)
    f, g = data(cfg, msh, eps, None, n) if u_exact is None else (-ufl.div(ufl.grad(u_exact)), 0)
    traction = None if u_exact is None else ufl.dot(ufl.grad(u_exact), n) * v * ds_c

    def term(penalty, kinked):
        """The Γ_C terms beside UFL by contact_quadrature exact or vertex (None under a Gauss rule)."""
        if isinstance(rule, int) or not (penalty or kinked):
            return None
        return contact.ContactTerm(u_h, domain.facet_tags, CONTACT, cfg.alpha, eps, rule, penalty,
                                   numpy_exact(cfg, msh.geometry.dim) if kinked else None)

    # on affine cells ∇u_h·∇v is a polynomial of degree 2(k−1): UFL's own estimate integrates it exactly
    stiffness = ufl.inner(ufl.grad(u_h), ufl.grad(v)) * ufl.dx(domain=msh)
    return forms.Boundary(u_h, u_h, u_exact, v, lambda u: ufl.dot(ufl.grad(u), n), traction, g, ds_c,
                          fem.Constant(msh, domain.h), term, stiffness, forms.on_mesh(f, msh) * v * dx, u_exact,
                          Trace(cfg, domain, u_h, u_exact), domain)


class Trace:
    """The scalar solution on Γ_C, what the measures read: w_h = u_h and w_ex = u_ex, the error seminorm,
    the penetration, the contact set and ∫[u_h]_+^beta (exact for P1), and the potential."""

    def __init__(self, cfg, domain, u_h, u_exact):
        self.cfg, self.domain, self.w_h, self.w_exact = cfg, domain, u_h, u_exact
        self._facets = None

    def facets(self):
        """(dofs, points) of the owned Γ_C facets (measure.contact_facet_dofs)."""
        if self._facets is None:
            self._facets = measure.contact_facet_dofs(self.w_h.function_space, self.domain.facet_tags, CONTACT)
        return self._facets

    def contact_variable(self, level):
        """(points, w_h, w_ex, seminorm) the Γ_C errors read: the facets' vertices, u_h's facet dof values,
        u_ex(facets, x) and |u_ex − u_h|_H1, the level's own H1 error (Lemma 3.1's left side)."""
        dofs, points = self.facets()
        u_ex = numpy_exact(self.cfg, self.domain.mesh.geometry.dim)
        vertices = points[:, :self.domain.mesh.topology.dim]
        return vertices, self.w_h.x.array[dofs], lambda facets, x: u_ex(x, level.eps), level.errors["H1"]

    def penetration(self):
        return measure.penetration(self.w_h, self.facets()[0])

    def contact_measure(self):
        return measure.contact_measure(self.w_h, *self.facets())

    def positive_power(self, beta):
        """∫_Γc [u_h]_+^beta, exact (contact.positive_power: for P1 the closed form of the solve's own term)."""
        dofs, points = self.facets()
        return contact.positive_power(self.domain.mesh.comm, self.w_h.x.array[dofs], points, beta,
                                      self.cfg.element.degree)

    def potential(self, eps, contact_energy):
        """The potential ½∫|∇u_h|² − ∫ f u_h + (contact_energy − ∫_Γc g u_h)/ε (measure.energy)."""
        msh = self.domain.mesh
        f, g = data(self.cfg, msh, eps, self.w_exact, ufl.FacetNormal(msh))
        degree = self.domain.quadrature[0] if self.domain.quadrature else QUADRATURE_DEGREE  # the solve's
        dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": degree})
        ds_c = self.domain.ds_c(degree)  # g u_h: smooth data times u_h
        return measure.energy(self.w_h, forms.on_mesh(f, msh), g, eps, dx, ds_c, contact_energy)


def numpy_exact(cfg, dim):
    """u_ex(points, eps) in numpy, points (..., 3)."""
    def evaluate(points, eps_value):
        variables = dict(zip(("x", "y", "z")[:dim], np.moveaxis(points, -1, 0)[:dim]), eps=eps_value)
        return cfg.problem.exact(variables, expressions.numpy_functions())
    return evaluate


def _variables(msh, eps):
    x = ufl.SpatialCoordinate(msh)
    names = ("x", "y", "z")[:msh.geometry.dim]
    return dict(zip(names, x), eps=eps)


def dirichlet_condition(V, domain, u_exact):
    """u = u_ex on Γ_D for manufactured scenes (u_ex vanishes there in the paper's setting), else 0."""
    dofs = fem.locate_dofs_topological(V, domain.mesh.topology.dim - 1, domain.facets(DIRICHLET))
    u_D = fem.Function(V)
    if u_exact is not None:
        u_D.interpolate(fem.Expression(u_exact, V.element.interpolation_points()))
    return fem.dirichletbc(u_D, dofs)
