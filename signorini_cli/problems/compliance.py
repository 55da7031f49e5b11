"""The compliance model in UFL: weak form (paper eq. (10)), positive part, manufactured data."""
from dataclasses import dataclass

import numpy as np

import ufl
from dolfinx import fem

from ..config import expressions
from ..meshing.meshes import CONTACT, DIRICHLET
from . import contact, element, measure

QUADRATURE_DEGREE = 6  # data terms (sin, exp ...) against the test functions, in Ω


@dataclass(frozen=True)
class Split:
    """F = F_fixed + F_varying and J = J_fixed + J_varying, where F_fixed (the load) and J_fixed (the
    stiffness) do not depend on u_h: Newton assembles them once per solve, then only the cheap rest."""
    F_fixed: ufl.Form
    J_fixed: ufl.Form
    F_varying: ufl.Form
    J_varying: ufl.Form  # None when no UFL term depends on u_h besides the stiffness


@dataclass(frozen=True)
class Forms:
    """Residual and Jacobian of one level, with the exact solution (if any) as UFL."""
    F: ufl.Form
    J: ufl.Form
    u_exact: object  # UFL expression, or None for data-only scenes
    ds_c: ufl.Measure
    split: Split = None
    contact: object = None  # contact.ContactTerm: Γ_C terms integrated beside UFL (contact_quadrature exact, vertex)
    near_nullspace: object = None  # PETSc.NullSpace the AMG preconditioner coarsens against (elasticity: rigid motions)
    gap: object = None  # (w_h, w_ex): the Γ_C quantity the contact measures read, when it is not u_h itself


def space(cfg, msh):
    """The scalar Lagrange space of the configured degree (element.degree)."""
    return element.space(msh, cfg.element.degree)


def errors(u_h, u_exact, h, degree=None):
    """{'L2', 'H1'}: ||u_ex − u_h||_{L2(Ω)} and the seminorm |u_ex − u_h|_{H1(Ω)}, MPI-reduced (`degree`: the
    quadrature the data need, else the element's default for h)."""
    return measure.errors(u_h, u_exact, h, degree)


def positive_part(u, positive, h, eps):
    """[u]_+ exactly, or smoothed as (u + sqrt(u^2 + delta^2))/2 with delta = delta(h, eps)."""
    if positive.kind == "exact":
        return ufl.conditional(ufl.gt(u, 0), u, 0)
    delta = positive.delta({"h": h, "eps": eps}, expressions.ufl_functions())
    return (u + ufl.sqrt(u**2 + delta**2)) / 2


def compliance(u, alpha, positive, h, eps):
    """The boundary law q_alpha(u) = [u]_+^alpha (paper eq. (4))."""
    return positive_part(u, positive, h, eps) ** alpha


def exact_solution(cfg, msh, eps):
    """u_ex as UFL in the mesh's spatial coordinates, or None."""
    if cfg.problem.exact is None:
        return None
    return on_mesh(cfg.problem.exact(_variables(msh, eps), expressions.ufl_functions()), msh)


def on_mesh(value, msh):
    """value as a UFL expression on msh: a constant ("5", "0*x", or f = -Δu of one) has no domain in
    UFL, which then can neither differentiate it nor build a form from it: make it a dolfinx Constant."""
    if ufl.domain.extract_domains(ufl.as_ufl(value)):
        return value
    return fem.Constant(msh, float(value))


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


def forms(cfg, domain, u_h, eps):
    """F(u_h; v) = ∫ ∇u_h·∇v + (1/eps) ∫_Γc [u_h]_+^alpha v − ∫ f v − (1/eps) ∫_Γc g v; J = dF/du.
    With contact_quadrature exact or vertex the kinked Γ_C terms, (1/eps)∫[u_h]_+^alpha v (exact positive
    part) and (1/eps)∫[u_ex]_+^alpha v of g, live in Forms.contact, outside the UFL forms."""
    msh = domain.mesh
    V = u_h.function_space
    v, du = ufl.TestFunction(V), ufl.TrialFunction(V)
    rule = cfg.contact_quadrature
    data_degree = domain.quadrature[0] if domain.quadrature else QUADRATURE_DEGREE  # as the data need (posed)
    degree = rule if isinstance(rule, int) else data_degree
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": data_degree})
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=domain.facet_tags,
                       metadata={"quadrature_degree": degree})(CONTACT)
    u_exact = exact_solution(cfg, msh, eps)
    f, g = data(cfg, msh, eps, u_exact, ufl.FacetNormal(msh))
    term = None if isinstance(rule, int) else contact_term(cfg, domain, u_h, eps, u_exact)
    if term is not None and term.u_exact is not None:  # its kinked part [u_ex]_+^alpha is the term's
        g = eps * ufl.dot(ufl.grad(u_exact), ufl.FacetNormal(msh))
    f, h = on_mesh(f, msh), fem.Constant(msh, domain.h)
    q = compliance(u_h, cfg.alpha, cfg.positive_part, h, eps)
    q = q if term is None or not term.penalty else 0
    # on affine cells ∇u_h·∇v is a polynomial of degree 2(k−1): UFL's own estimate integrates it exactly
    stiffness = ufl.inner(ufl.grad(u_h), ufl.grad(v)) * ufl.dx(domain=msh)
    load = f * v * dx
    boundary = (q - g) / eps * v * ds_c if not (_is_zero(q) and _is_zero(g)) else None
    varying = stiffness if boundary is None else stiffness + boundary
    F = varying - load
    J_varying = None if _is_zero(q) else ufl.derivative(boundary, u_h, du)
    split = Split(F_fixed=-load, J_fixed=ufl.derivative(stiffness, u_h, du), F_varying=varying, J_varying=J_varying)
    return Forms(F, ufl.derivative(F, u_h, du), u_exact, ds_c, split, term)


def contact_term(cfg, domain, u_h, eps, u_exact):
    """The Γ_C terms integrated beside UFL by cfg.contact_quadrature (exact or vertex): the penalty for
    the exact positive part, and the kinked data [u_ex]_+^alpha of a manufactured compliance solution."""
    penalty = cfg.positive_part.kind == "exact"
    kinked = u_exact is not None and cfg.problem.exact_solves != "signorini"
    if not (penalty or kinked):
        return None
    return contact.ContactTerm(u_h, domain.facet_tags, CONTACT, cfg.alpha, eps, cfg.contact_quadrature,
                               penalty, numpy_exact(cfg, domain.mesh.geometry.dim) if kinked else None)


def numpy_exact(cfg, dim):
    """u_ex(points, eps) in numpy, points (..., 3)."""
    def evaluate(points, eps_value):
        variables = dict(zip(("x", "y", "z")[:dim], np.moveaxis(points, -1, 0)[:dim]), eps=eps_value)
        return cfg.problem.exact(variables, expressions.numpy_functions())
    return evaluate


def _is_zero(value):
    return isinstance(value, (int, float)) and value == 0


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
