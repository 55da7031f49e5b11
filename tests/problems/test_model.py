"""The weak form's Γ_C terms on a closed-form case: u_h = x - 0.3 on the bottom face, whose zero
x = 0.3 lies inside a facet of N = 4, so that (1/eps)∫_Γc [u_h]_+^alpha v has exact values in closed form."""
import numpy as np
import pytest
from mpi4py import MPI

from dolfinx import fem
from signorini_cli.meshing import meshes
from signorini_cli.problems.registry import problem_of

EPS = 0.5
ZERO = 0.3  # u_h = x - ZERO is P1: the interpolant is exact, and psi(u_h) kinks at x = ZERO, inside [0.25, 0.5]


def level(make_config, **changes):
    cfg = make_config(**dict({"problem": {"exact": None, "f": "0", "g": "0"}}, **changes))
    domain = meshes.build(cfg.mesh, cfg.contact, 4, MPI.COMM_SELF)
    u_h = fem.Function(fem.FunctionSpace(domain.mesh, ("Lagrange", 1)))
    u_h.interpolate(lambda x: x[0] - ZERO)
    return problem_of(cfg).forms(cfg, domain, u_h, fem.Constant(domain.mesh, EPS)), u_h


def contact_integrals(alpha):
    """(1/eps) (∫_0^1 [x - z]_+^alpha dx, ∫_0^1 [x - z]_+^alpha x dx, ∫_0^1 alpha [x - z]_+^(alpha-1) dx)."""
    r = 1 - ZERO
    return (r ** (alpha + 1) / (alpha + 1) / EPS,
            (r ** (alpha + 2) / (alpha + 2) + ZERO * r ** (alpha + 1) / (alpha + 1)) / EPS, r ** alpha / EPS)


@pytest.mark.parametrize("alpha", [1.0, 1.5, 2.0, 3.0])
def test_exact_contact_term_integrates_the_kink(make_config, alpha):
    forms, u_h = level(make_config, alpha=alpha)
    term = forms.contact
    residual = term.residual(u_h.x.array)
    x = term.points[..., 0]
    total, moment, slope = contact_integrals(alpha)
    # v = 1 and v = x are P1: sum_i R_i v_i = (1/eps)∫ [u_h]_+^alpha v; round-off only
    assert residual.sum() == pytest.approx(total, rel=1e-13)
    assert (residual * x).sum() == pytest.approx(moment, rel=1e-13)
    assert term.jacobian(u_h.x.array).sum() == pytest.approx(slope, rel=1e-13)


def test_vertex_rule_is_the_trapezoid_rule(make_config):
    forms, u_h = level(make_config, alpha=2.0, contact_quadrature="vertex")
    # nodes x = 0, 1/4, ..., 1: [x - 0.3]_+^2 = 0, 0, 0.04, 0.2025, 0.49; trapezoid weights 1/8, 1/4 ..., 1/8
    trapezoid = (0.25 * (0.04 + 0.2025) + 0.125 * 0.49) / EPS
    assert forms.contact.residual(u_h.x.array).sum() == pytest.approx(trapezoid, rel=1e-14)
    jacobian = forms.contact.jacobian(u_h.x.array)
    assert np.count_nonzero(jacobian - jacobian * np.eye(2)) == 0  # lumped: diagonal per facet
    assert jacobian.sum() == pytest.approx((0.25 * 2 * (0.2 + 0.45) + 0.125 * 2 * 0.7) / EPS, rel=1e-14)


def test_gauss_degree_stays_in_ufl(make_config):
    forms, _ = level(make_config, contact_quadrature=6)
    assert forms.contact is None  # the whole weak form in UFL
    assert forms.ds_c.metadata() == {"quadrature_degree": 6}
    assert any(itg.integral_type() == "exterior_facet" for itg in forms.split.J_varying.integrals())


def test_exact_rule_leaves_the_kinked_terms_out_of_ufl(make_config):
    forms, _ = level(make_config, problem={"exact": "sin(2*pi*x)*(1-y)**2"})
    assert forms.split.J_varying is None  # no UFL term but the stiffness depends on u_h
    assert forms.contact.penalty and forms.contact.u_exact is not None


def test_smooth_positive_part_keeps_ufl_penalty(make_config):
    forms, _ = level(make_config, positive_part={"kind": "smooth"}, problem={"exact": "sin(2*pi*x)*(1-y)**2"})
    assert not forms.contact.penalty and forms.contact.u_exact is not None  # only the kinked data term
    assert forms.split.J_varying is not None
