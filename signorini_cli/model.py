"""The compliance model in UFL: weak form (SPEC; paper eq. (10)), positive part, manufactured data."""
from dataclasses import dataclass

import ufl
from dolfinx import fem

from . import expressions
from .meshes import CONTACT, DIRICHLET

QUADRATURE_DEGREE = 6  # data terms (sin, exp ...) and the kinked [u_h]_+^alpha on Γ_C


@dataclass(frozen=True)
class Split:
    """F = F_fixed + F_varying and J = J_fixed + J_varying, where F_fixed (the load) and J_fixed (the
    stiffness) do not depend on u_h: Newton assembles them once per solve, then only the cheap rest."""
    F_fixed: ufl.Form
    J_fixed: ufl.Form
    F_varying: ufl.Form
    J_varying: ufl.Form


@dataclass(frozen=True)
class Forms:
    """Residual and Jacobian of one level, with the exact solution (if any) as UFL."""
    F: ufl.Form
    J: ufl.Form
    u_exact: object  # UFL expression, or None for data-only scenes
    ds_c: ufl.Measure
    split: Split = None


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
    return cfg.problem.exact(_variables(msh, eps), expressions.ufl_functions())


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
    """F(u_h; v) = ∫ ∇u_h·∇v + (1/eps) ∫_Γc [u_h]_+^alpha v − ∫ f v − (1/eps) ∫_Γc g v, and J = dF/du."""
    msh = domain.mesh
    V = u_h.function_space
    v, du = ufl.TestFunction(V), ufl.TrialFunction(V)
    metadata = {"quadrature_degree": QUADRATURE_DEGREE}
    dx = ufl.Measure("dx", domain=msh, metadata=metadata)
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=domain.facet_tags, metadata=metadata)(CONTACT)
    u_exact = exact_solution(cfg, msh, eps)
    f, g = data(cfg, msh, eps, u_exact, ufl.FacetNormal(msh))
    h = fem.Constant(msh, domain.h)
    q = compliance(u_h, cfg.alpha, cfg.positive_part, h, eps)
    # P1 gradients are constant on (affine) cells: the stiffness is exact with UFL's own degree (0)
    stiffness = ufl.inner(ufl.grad(u_h), ufl.grad(v)) * ufl.dx(domain=msh)
    load, contact = f * v * dx, (q - g) / eps * v * ds_c
    F = stiffness + contact - load
    split = Split(F_fixed=-load, J_fixed=ufl.derivative(stiffness, u_h, du),
                  F_varying=stiffness + contact, J_varying=ufl.derivative(contact, u_h, du))
    return Forms(F, ufl.derivative(F, u_h, du), u_exact, ds_c, split)


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
