"""The normal-compliance (penalty) method: the contact condition enters as the boundary law
ε σ_n(u) + [w]_+^α = g on Γ_C (paper eq. (4), weak form (10)), built once for every problem from its
Boundary; its Γ_C quantities (the contact force (1/ε)∫[w_h]_+^α, the potential) read the problem's trace."""
import ufl

from .. import config
from ..analysis import verdict
from ..config import expressions, names
from . import forms as forms_, measure

NAME = "penalty"
EPSILON = True  # the discrete problem depends on ε (the solver may continue in it)
MEASURES = names.MEASURE_KEYS  # every verification measure: they are the paper's
expected = verdict.expected  # the paper's rates (analysis.rates.PAPER_RATES) under its hypotheses


def parameters(cfg):
    """The method's parameters in a line: α and the ε law."""
    law = "θ" + config.LAWS[cfg.epsilon.law].text.format(p=cfg.epsilon.p)
    return f"α = {cfg.alpha:g}, ε = {law}, θ = {cfg.epsilon.theta:g}"


def positive_part(u, positive, h, eps):
    """[u]_+ exactly, or smoothed as (u + sqrt(u^2 + delta^2))/2 with delta = delta(h, eps)."""
    if positive.kind == "exact":
        return ufl.conditional(ufl.gt(u, 0), u, 0)
    delta = positive.delta({"h": h, "eps": eps}, expressions.ufl_functions())
    return (u + ufl.sqrt(u**2 + delta**2)) / 2


def compliance(u, alpha, positive, h, eps):
    """The boundary law q_alpha(u) = [u]_+^alpha (paper eq. (4))."""
    return positive_part(u, positive, h, eps) ** alpha


def forms(cfg, boundary, eps):
    """F(u_h; v) = a(u_h, v) + (1/ε)∫_Γc ([w_h]_+^α − [w_ex]_+^α − g) v_n − ∫ f v − ∫_Γc σ(u_ex)n·v: a
    manufactured u_ex solves the compliance model when its data are the traction of u_ex and its kinked
    [w_ex]_+^α; a Signorini solution u_S (exact_solves: signorini) has g = 0. With contact_quadrature exact
    or vertex the kinked terms live in Forms.contact, outside the UFL forms (contact.ContactTerm)."""
    kinked = boundary.u_exact is not None and cfg.problem.exact_solves == "compliance"
    term = boundary.term(cfg.positive_part.kind == "exact", kinked)
    q = 0 if term is not None and term.penalty else compliance(
        boundary.w_h, cfg.alpha, cfg.positive_part, boundary.h, eps)
    exact_pp = type(cfg.positive_part)()  # the data use the exact positive part: u_ex solves the exact model
    kink = 0 if not kinked or (term is not None and term.u_exact is not None) else compliance(
        boundary.w_exact, cfg.alpha, exact_pp, None, eps)
    load = boundary.load + boundary.traction if kinked else boundary.load
    data = kink if forms_.is_zero(boundary.g) else kink + boundary.g
    contact_form = None
    if not (forms_.is_zero(q) and forms_.is_zero(data)):
        contact_form = (q - data) / eps * boundary.v_n * boundary.ds_c
    return forms_.assemble(boundary, contact_form, term, not forms_.is_zero(q), load)


def contact_errors(cfg, comm, points, w_h, w, eps, seminorm):
    """Γ_C errors of w_h against w on the facets `points`: L2(Γ_C), the positive parts in L^{α+1}(Γ_C) and the
    penalty energy (|e|² + ε⁻¹‖[w]_+ − [w_h]_+‖^{α+1})^{1/2} of Lemma 3.1 (measure.contact_errors)."""
    return measure.contact_errors(comm, points, w_h, w, eps, cfg.alpha, seminorm)


def quantities(cfg, forms, eps, wanted):
    """The method's Γ_C quantities: the contact set {w_h > 0} (where the penalty acts), the contact force
    (1/ε)∫_Γc [w_h]_+^α and the potential J(u_h) = ½a(u_h, u_h) − ∫ f u_h + (1/ε)∫_Γc ([w_h]_+^{α+1}/(α+1)
    − g u_h) where the problem has one."""
    found, trace = {}, forms.trace
    if "contact_measure" in wanted:
        found["contact_measure"] = trace.contact_measure()
    if "contact_force" in wanted:
        found["contact_force"] = trace.positive_power(cfg.alpha) / eps
    if "energy" in wanted:
        energy = trace.potential(eps, trace.positive_power(cfg.alpha + 1) / (cfg.alpha + 1))
        if energy is not None:
            found["energy"] = energy
    return found
