"""The Γ_C terms integrated beside UFL: the exact P1 integrals against brute-force quadrature
on random and degenerate facets, the adaptive data term against mpmath, and a 2-rank run equal to 1 rank."""
import warnings

import mpmath
import numpy as np
import pytest
import yaml
from mpi4py import MPI
from scipy import integrate

from signorini_cli import config, studies
from signorini_cli.problems import contact
from conftest import BASE, merge

ALPHAS = (1.0, 1.5, 2.0, 3.0)
TOL = 1e-12  # the accuracy target, relative to the largest entry (brute force: 1e-14 or better)
RNG = np.random.default_rng(17)
SEGMENTS = [RNG.normal(size=2) for _ in range(4)] + [
    np.array(c) for c in ([1.0, 1.0 + 1e-9], [1.0, 1.0], [0.0, 1.0], [-1.0, -2.0], [1.0, 2.0], [1e-3, 1.0],
                          [1.0, 0.75], [1.0, -1e-12], [-0.5, 0.5])]  # nearly equal, one zero, all of one sign
TRIANGLES = [RNG.normal(size=3) for _ in range(2)] + [
    np.array(c) for c in ([1.0, 1.0 + 1e-9, 1.0 - 1e-9], [0.0, 1.0, 0.5], [1.0, 2.0, 3.0], [1e-3, 1.0, 0.5],
                          [1.0, 1.0, -1e-9], [1.0, 1.0 + 1e-10, -1.0], [-1.0, -2.0, -0.1], [0.0, 0.0, 1.0])]


def psi(t, beta):
    return float(t > 0) * max(t, 0) ** beta


def brute_segment(u, beta):
    """Means over [0, 1] of psi(l) lambda_i lambda_j by mpmath (30 digits), split at the zero of l."""
    mpmath.mp.dps = 30
    u0, u1 = (mpmath.mpf(float(v)) for v in u)
    cut = [0, u0 / (u0 - u1), 1] if (u0 > 0) != (u1 > 0) else [0, 1]
    lam = (lambda t: 1 - t, lambda t: t)
    return np.array([[float(mpmath.quad(lambda t: psi(u0 + (u1 - u0) * t, beta) * lam[i](t) * lam[j](t), cut))
                      for j in range(2)] for i in range(2)])


def brute_triangle(u, beta):
    """Means over the reference triangle of psi(l) lambda_i lambda_j by nested adaptive QUADPACK, each
    split where l (inner) or the zero line's exit through an edge (outer) makes the integrand kink."""
    u0, u1, u2 = (float(v) for v in u)

    def inner(x, i, j):
        a, b = u0 + (u1 - u0) * x, u2 - u0  # l = a + b y on 0 <= y <= 1 - x
        cut = [-a / b] if b != 0 and 0 < -a / b < 1 - x else None
        lam = lambda y: (1 - x - y, x, y)  # noqa: E731
        return integrate.quad(lambda y: psi(a + b * y, beta) * lam(y)[i] * lam(y)[j], 0, 1 - x, points=cut,
                              epsabs=0, epsrel=1e-13, limit=200)[0]
    kinks = [p for p in (u0 / (u0 - u1) if u1 != u0 else -1, u2 / (u2 - u1) if u2 != u1 else -1) if 0 < p < 1]
    out = np.zeros((3, 3))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", integrate.IntegrationWarning)  # round-off at 1e-13 is reported
        for i in range(3):
            for j in range(i, 3):
                out[i, j] = out[j, i] = 2 * integrate.quad(inner, 0, 1, args=(i, j), points=kinks or None,
                                                           epsabs=0, epsrel=1e-13, limit=200)[0]
    return out


def assert_moments(u, beta, brute):
    """m2 against the brute force, and m1 against its row sums (sum_j lambda_j = 1)."""
    _, m1, m2 = contact.moments(u[None, :], beta)
    scale = np.abs(brute).max() or 1.0
    assert np.abs(m2[0] - brute).max() <= TOL * scale
    assert np.abs(m1[0] - brute.sum(axis=1)).max() <= TOL * scale


@pytest.mark.parametrize("alpha", ALPHAS)
@pytest.mark.parametrize("u", SEGMENTS, ids=lambda u: np.array2string(u, precision=3))
def test_segment_moments_match_mpmath(u, alpha):
    for beta in (alpha, alpha - 1):  # the residual's psi and the Jacobian's psi' / alpha
        assert_moments(u, beta, brute_segment(u, beta))


@pytest.mark.parametrize("alpha", ALPHAS)
@pytest.mark.parametrize("u", TRIANGLES, ids=lambda u: np.array2string(u, precision=3))
def test_triangle_moments_match_quadpack(u, alpha):
    for beta in (alpha, alpha - 1):
        assert_moments(u, beta, brute_triangle(u, beta))


def test_moments_of_constant_and_integer_powers():
    # closed forms: l = 2 on the triangle: mean of lambda_i = 1/3, of lambda_i^2 = 1/6, lambda_i lambda_j = 1/12
    m0, m1, m2 = contact.moments(np.array([[2.0, 2.0, 2.0]]), 1.5)
    assert m0[0] == pytest.approx(2**1.5, rel=1e-15)
    assert m1[0] == pytest.approx([2**1.5 / 3] * 3, rel=1e-15)
    assert m2[0] == pytest.approx(2**1.5 * (np.eye(3) / 12 + 1 / 12), rel=1e-15)
    # l = t on [0, 1]: ∫ t^2 (1 - t) = 1/12, ∫ t^3 = 1/4
    _, m1, _ = contact.moments(np.array([[0.0, 1.0]]), 2.0)
    assert m1[0] == pytest.approx([1 / 12, 1 / 4], rel=1e-15)


def u_numpy(points):
    """sin(7x) cos(3y) + 0.1: its zeros cross the facets at random places."""
    return np.sin(7 * points[..., 0]) * np.cos(3 * points[..., 1]) + 0.1


def mpmath_segment_data(p0, p1, alpha):
    """∫_S [u]_+^alpha lambda_i by mpmath, split at the zeros of u (found on a fine grid)."""
    mpmath.mp.dps = 25
    p0, p1 = [mpmath.mpf(float(v)) for v in p0[:2]], [mpmath.mpf(float(v)) for v in p1[:2]]

    def g(t):
        x, y = p0[0] + t * (p1[0] - p0[0]), p0[1] + t * (p1[1] - p0[1])
        return mpmath.sin(7 * x) * mpmath.cos(3 * y) + 0.1
    grid = [mpmath.mpf(k) / 64 for k in range(65)]
    cut = [0] + [mpmath.findroot(g, (a, b), solver="anderson") for a, b in zip(grid, grid[1:])
                 if (g(a) > 0) != (g(b) > 0)] + [1]
    length = mpmath.sqrt((p1[0] - p0[0]) ** 2 + (p1[1] - p0[1]) ** 2)
    return np.array([float(length * mpmath.quad(lambda t: psi(g(t), alpha) * w(t), cut))
                     for w in (lambda t: 1 - t, lambda t: t)])


@pytest.mark.parametrize("alpha", ALPHAS)
def test_data_term_on_segments_matches_mpmath(alpha):
    starts = RNG.uniform(size=(6, 3)) * [1, 1, 0]
    points = np.stack((starts, starts + RNG.uniform(-0.1, 0.1, size=(6, 3)) * [1, 1, 0]), axis=1)  # h <= 0.14
    found = contact.data_on_segments(u_numpy, alpha, points)
    expected = np.array([mpmath_segment_data(p[0], p[1], alpha) for p in points])
    # 1e-12 of the largest entry: the segments' sizes are a mesh's (h <= 0.14), not the whole domain
    assert np.abs(found - expected).max() <= TOL * np.abs(expected).max()


@pytest.mark.parametrize("alpha", ALPHAS)
def test_data_term_on_triangles_converges(alpha, monkeypatch):
    # the adaptive rule against itself with 4x the points and 8x the sign samples, on triangles of
    # size h <= 0.05 (3-D levels N >= 20): far below the discretisation error h^2 ~ 2.5e-3
    corners = RNG.uniform(size=(200, 1, 3)) * [1, 1, 0]
    points = corners + RNG.uniform(size=(200, 3, 3)) * [0.05, 0.05, 0]
    found = contact.data_on_triangles(u_numpy, alpha, points)
    monkeypatch.setattr(contact, "GAUSS_POINTS", 40)
    monkeypatch.setattr(contact, "SIGN_SAMPLES", 32)
    fine = contact.data_on_triangles(u_numpy, alpha, points)
    assert np.abs(found - fine).max() <= 1e-10 * np.abs(fine).max()


def test_data_term_vanishes_where_u_is_negative():
    points = np.array([[[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]]])
    assert contact.data_on_segments(lambda x: -1.0 - x[..., 0], 2.0, points) == pytest.approx(0.0, abs=0.0)


# --- serial and 2 ranks ------------------------------------------------------------------------------------

STIFF = {"alpha": 1.5, "epsilon": {"law": "constant", "theta": 1e-6}, "mesh": {"refinements": [8, 16]}}
CUBE = {"dimension": 3, "alpha": 1.0, "mesh": {"kind": "unit_cube", "refinements": [4]},
        "problem": {"exact": "sin(2*pi*x)*sin(pi*y)*(1-z)**2 + 0.1*(1-z)"}}


@pytest.mark.mpi
@pytest.mark.parametrize("changes", [pytest.param(STIFF, id="2d-stiff"), pytest.param(CUBE, id="3d-alpha1")])
def test_two_ranks_match_one(changes):
    comm = MPI.COMM_WORLD
    assert comm.size == 2
    cfg = config.loads(yaml.safe_dump(merge(BASE, dict(changes, solver={"rtol": 1e-12, "stol": 1e-12}))))
    parallel = studies.run_study(cfg, comm=comm)
    serial = studies.run_study(cfg, comm=MPI.COMM_SELF)
    for p, s in zip(parallel, serial):
        assert p.outcome.converged and s.outcome.converged
        for norm in ("L2", "H1"):  # tight solves: the two differ by round-off in the sums only
            assert p.errors[norm] == pytest.approx(s.errors[norm], rel=1e-10)


@pytest.mark.parametrize("n", [64, 128])
def test_data_term_with_a_zero_on_a_vertex_matches_mpmath(n):
    # u = sin(2 pi x) on y = 0 has its zero x = 1/2 on a vertex, where numpy gives 1.2e-16, not 0: the
    # segment ending there is kinked like (1/2 - x)^1.5 and needs the Gauss-Jacobi piece
    alpha = 1.5
    points = np.array([[[0.5 - 1 / n, 0, 0], [0.5, 0, 0]], [[0.5, 0, 0], [0.5 + 1 / n, 0, 0]]])
    u_fn = contact.snap_zeros(lambda x: np.sin(2 * np.pi * x[..., 0]), points)
    found = contact.data_on_segments(u_fn, alpha, points)
    mpmath.mp.dps = 30
    expected = np.array([[float(mpmath.quad(lambda t: psi(mpmath.sin(2 * mpmath.pi * (p[0][0] + t / n)), alpha)
                                             * w(t), [0, 1]) / n) for w in (lambda t: 1 - t, lambda t: t)]
                         for p in points])
    assert np.abs(found - expected).max() <= 1e-12 * np.abs(expected).max()  # the bar: 1e-12


# --- P2: each segment cut at the zeros of the quadratic trace and of the data --------------------------

def composite(points, integrand, kinks, pieces=2000):
    """kinked.on_facets by brute force on segments: a 3-point Gauss-Legendre rule on each of `pieces` equal
    sub-intervals of every facet, blind to the kinks (its error at a kink of [.]_+^2 is ~pieces^-3)."""
    x, w = np.polynomial.legendre.leggauss(3)
    t = ((np.arange(pieces)[:, None] + (x + 1) / 2) / pieces).ravel()
    weights = np.tile(w / 2, pieces) / pieces
    m = len(points)
    lam = np.broadcast_to(np.stack((1 - t, t), axis=-1), (m, t.size, 2))
    xs = points[:, None, 0] + t[None, :, None] * (points[:, 1] - points[:, 0])[:, None]
    values = integrand(np.arange(m), lam, xs)
    lengths = np.linalg.norm(points[:, 1] - points[:, 0], axis=1)
    return np.einsum("pq...,q,p->p...", values, weights, lengths)


P2_KINKED = {"element": {"degree": 2}, "epsilon": {"law": "theta_h", "theta": 0.01},
             "mesh": {"refinements": [16, 32, 64]}, "problem": {"exact": "sin(2*pi*(x-0.3))*(1-y)**2"},
             "verification": {"measures": []}}


def test_p2_solution_as_with_a_fine_composite_rule(make_config, monkeypatch):
    """P2, u_ex = sin(2π(x − 0.3))(1 − y)², α = 2, ε = 0.01h, N = 16 … 64: L2 and H1 of the exact contact rule
    equal those of the same discrete problem with its contact and data terms by a 6000-point composite rule per
    facet to 1e-7 relative (a degree-8 Gauss rule is off by 1.4e-3 in L2 at N = 16, 4.9e-5 at N = 64)."""
    from signorini_cli.problems import kinked
    cfg = make_config(**P2_KINKED)
    exact = studies.run_study(cfg, comm=MPI.COMM_SELF)
    monkeypatch.setattr(kinked, "on_facets", composite)
    fine = studies.run_study(cfg, comm=MPI.COMM_SELF)
    for one, two in zip(exact, fine):
        assert one.outcome.converged and two.outcome.converged
        for norm in ("L2", "H1"):
            assert one.errors[norm] == pytest.approx(two.errors[norm], rel=1e-7), (one.n, norm)
