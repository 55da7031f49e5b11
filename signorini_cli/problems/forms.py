"""What a problem and its contact method share: the residual and Jacobian of a level (Forms, Split), the
problem's side of Γ_C handed to the method (Boundary), and the assembly of the two into Forms."""
from dataclasses import dataclass

import ufl
from dolfinx import fem

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
    trace: object = None  # the problem's Γ_C trace the measures read (w_h, w_ex, penetration, contact set ...)
    gap: object = None  # the trace again where the contact variable is not u_h itself (elasticity: u_h·n − g0)


@dataclass(frozen=True)
class Boundary:
    """A problem's side of Γ_C, handed to the method that enforces the contact condition there: the
    contact variable w (u, or u·n − g0) of u_h and of u_ex, the test function's part v_n the contact force
    acts on (v, or v·n), the normal stress flux(u) (∂_n u, or σ_n(u)), the traction of u_ex on Γ_C as a load
    (a manufactured compliance solution's data), the compliance data g of data-only scenes, and
    `term(penalty, kinked)`: the Γ_C terms integrated beside UFL on w (None under a Gauss rule)."""
    u_h: fem.Function
    w_h: object
    w_exact: object
    v_n: object
    flux: object
    traction: object  # UFL form or None
    g: object  # UFL expression or 0
    ds_c: ufl.Measure
    h: fem.Constant
    term: object
    stiffness: ufl.Form
    load: ufl.Form
    u_exact: object
    trace: object
    domain: object
    near_nullspace: object = None
    gap: object = None  # the trace where w is not u_h itself (Forms.gap)


def on_mesh(value, msh):
    """value as a UFL expression on msh: a constant ("5", "0*x", or f = -Δu of one) has no domain in
    UFL, which then can neither differentiate it nor build a form from it: make it a dolfinx Constant."""
    if ufl.domain.extract_domains(ufl.as_ufl(value)):
        return value
    return fem.Constant(msh, float(value))


def is_zero(value):
    """A Python number 0: a term that is absent, not a UFL expression that happens to vanish."""
    return isinstance(value, (int, float)) and value == 0


def assemble(boundary, contact_form, term, nonlinear, load, linear=None):
    """Forms of F = stiffness + linear + contact_form − load (contact_form None: no UFL Γ_C term; `linear`: a
    method's Γ_C term linear in u_h, None or a form) and J = dF/du, split into the parts that do not depend on
    u_h (load; stiffness and `linear`) and the rest; `nonlinear`: whether contact_form depends on u_h (else
    J_varying is None)."""
    u_h = boundary.u_h
    du = ufl.TrialFunction(u_h.function_space)
    stiffness = boundary.stiffness if linear is None else boundary.stiffness + linear
    varying = stiffness if contact_form is None else stiffness + contact_form
    F = varying - load
    J_varying = ufl.derivative(contact_form, u_h, du) if nonlinear else None
    split = Split(F_fixed=-load, J_fixed=ufl.derivative(stiffness, u_h, du), F_varying=varying, J_varying=J_varying)
    return Forms(F, ufl.derivative(F, u_h, du), boundary.u_exact, boundary.ds_c, split, term,
                 boundary.near_nullspace, boundary.trace, boundary.gap)
