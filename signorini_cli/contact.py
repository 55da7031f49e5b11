"""The compliance term (1/eps)∫_Γc [u_h]_+^alpha v of the P1 solution, its Jacobian and the kinked data
term (1/eps)∫_Γc [u_ex]_+^alpha v, integrated exactly (or nodally) on the rank's Γ_C facets and added
beside the UFL forms into the PETSc residual and Jacobian (issue 17)."""
import math

import numpy as np
from scipy import special

SERIES_SPREAD = 0.25  # series about the mean value c when every |u_j - c| <= c/4: terms shrink like 4^-j
SERIES_TERMS = 32  # C(j+4, 4) 4^-j < 1e-14 from j = 32 on (at most 5 points in a divided difference)


# --- exact means over a simplex of psi(l) lambda^m, psi(t) = t_+^beta, l linear ------------------------

def psi(t, beta):
    """t_+^beta, with t_+^0 the Heaviside function (0 at t = 0): the generalised derivative for alpha = 1."""
    positive = t > 0
    return np.where(positive, np.where(positive, t, 1.0) ** beta, 0.0)


def moments(u, beta):
    """(m0, m1, m2): the means over the simplex of psi(l), psi(l) lambda_i and psi(l) lambda_i lambda_j for
    the linear l with vertex values u, shape (facets, n+1); exact for any beta >= 0 (0: Heaviside)."""
    facets, k = u.shape
    if k == 1:
        p = psi(u[:, 0], beta)
        return p, p[:, None], p[:, None, None]
    m0, m1, m2 = np.zeros(facets), np.zeros((facets, k)), np.zeros((facets, k, k))
    c = u.mean(axis=1)
    smooth = (u.min(axis=1) > 0) & (np.abs(u - c[:, None]).max(axis=1) <= SERIES_SPREAD * c)
    cut = (u.max(axis=1) > 0) & ~smooth
    for mask, method in ((smooth, _series), (cut, _cones)):
        if mask.any():
            m0[mask], m1[mask], m2[mask] = method(u[mask], beta)
    return m0, m1, m2


def _series(u, beta):
    """Moments from (c + d)^beta = sum_j binom(beta, j) c^(beta-j) d^j, d = l - c, with the exact simplex
    means of d^j lambda^m = n! m! j!/(j+n+|m|)! h_j(d, d_i (m_i times)), h_j the complete homogeneous
    symmetric polynomial (Hermite-Genocchi for the monomial t^(j+n+|m|))."""
    facets, k = u.shape
    n = k - 1
    c = u.mean(axis=1)
    e = u / c[:, None] - 1.0
    h = _homogeneous(e, SERIES_TERMS)  # (terms, facets)
    h1 = _extend(h[:, :, None], e)  # (terms, facets, k): one more variable e_i
    h2 = _extend(h1[..., None], e[:, None, :])  # (terms, facets, k, k): e_i and e_j
    weights = [np.empty(SERIES_TERMS) for _ in range(3)]
    for extra in range(3):  # coefficient of term j: falling(beta, j) n!/(j+n+extra)!
        coef = math.factorial(n) / math.factorial(n + extra)
        for j in range(SERIES_TERMS):
            weights[extra][j] = coef
            coef *= (beta - j) / (j + 1 + n + extra)
    scale = c**beta
    m0 = scale * np.tensordot(weights[0], h, axes=(0, 0))
    m1 = scale[:, None] * np.tensordot(weights[1], h1, axes=(0, 0))
    m2 = scale[:, None, None] * np.tensordot(weights[2], h2, axes=(0, 0))
    m2 *= 1 + np.eye(k)  # m! = 2 on the diagonal
    return m0, m1, m2


def _homogeneous(e, terms):
    """h_j(e_0 .. e_n) for j < terms, by adding one variable at a time: h_j <- h_j + e_i h_{j-1}."""
    h = np.zeros((terms, e.shape[0]))
    h[0] = 1.0
    for i in range(e.shape[1]):
        for j in range(1, terms):
            h[j] += e[:, i] * h[j - 1]
    return h


def _extend(h, e):
    """h_j with one more variable e, broadcast against h's trailing axes: h_j <- h_j + e h_{j-1}."""
    out = np.broadcast_to(h, np.broadcast_shapes(h.shape, (1,) + e.shape)).copy()
    for j in range(1, out.shape[0]):
        out[j] += e * out[j - 1]
    return out


def _cones(u, beta):
    """Moments by the cone decomposition S = sum_k zeta_k cone(Z, face_k) from the point Z where l = 0 on
    the line through the largest and smallest vertex values (inside S when l changes sign, beyond the
    smallest vertex when all are positive): on cone_k, l = (1-w) l_k with w Z's weight, so
    psi(l) = (1-w)^beta psi(l_k) and each cone reduces to its face, one dimension lower."""
    facets, k = u.shape
    rows = np.arange(facets)
    top, low = u.argmax(axis=1), u.argmin(axis=1)
    low = np.where(low == top, (top + 1) % k, low)  # equal values: any other vertex
    s = u[rows, top] / (u[rows, top] - u[rows, low])
    zeta = np.zeros((facets, k))
    zeta[rows, top], zeta[rows, low] = 1 - s, s
    m0, m1, m2 = np.zeros(facets), np.zeros((facets, k)), np.zeros((facets, k, k))
    for opposite in (top, low):
        cone = _cone(u, opposite, zeta, beta)
        weight = zeta[rows, opposite]
        m0 += weight * cone[0]
        m1 += weight[:, None] * cone[1]
        m2 += weight[:, None, None] * cone[2]
    return m0, m1, m2


def _cone(u, opposite, zeta, beta):
    """Means over cone(Z, face opposite vertex `opposite`): lambda_i = w zeta_i + (1-w) tau_i, the
    radial parts n ∫ w^a (1-w)^(n-1+beta+b) dw = n B(a+1, n+beta+b) exact."""
    facets, k = u.shape
    n = k - 1
    face = np.array([[i for i in range(k) if i != o] for o in range(k)])[opposite]  # (facets, n)
    f0, f1_face, f2_face = moments(np.take_along_axis(u, face, axis=1), beta)
    rows = np.arange(facets)[:, None]
    f1 = np.zeros((facets, k))
    f1[rows, face] = f1_face
    f2 = np.zeros((facets, k, k))
    f2[rows[:, :, None], face[:, :, None], face[:, None, :]] = f2_face

    def radial(a, b):
        return n * special.beta(a + 1, n + beta + b)

    zz = zeta[:, :, None] * zeta[:, None, :]
    zf = zeta[:, :, None] * f1[:, None, :]
    m0 = radial(0, 0) * f0
    m1 = radial(1, 0) * zeta * f0[:, None] + radial(0, 1) * f1
    m2 = radial(2, 0) * zz * f0[:, None, None] + radial(1, 1) * (zf + zf.transpose(0, 2, 1)) + radial(0, 2) * f2
    return m0, m1, m2
