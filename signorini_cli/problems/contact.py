"""The compliance term (1/eps)∫_Γc [u_h]_+^alpha v of the P1 solution, its Jacobian and the kinked data
term (1/eps)∫_Γc [u_ex]_+^alpha v, integrated exactly (or nodally) on the rank's Γ_C facets and added
beside the UFL forms into the PETSc residual and Jacobian."""
import math

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc
from scipy import special

from ..config import ConfigError
from . import element, kinked, measure

SERIES_SPREAD = 0.25  # series about the mean value c when every |u_j - c| <= c/4: terms shrink like 4^-j
SERIES_TERMS = 32  # C(j+4, 4) 4^-j < 1e-14 from j = 32 on (at most 5 points in a divided difference)
# the exact rule integrates the data term [u_ex]_+^alpha by Gauss-Jacobi with the weight |t|^alpha, whose
# weights carry 2^-(alpha+1) (scipy.special.roots_jacobi, _pieces): out of double range from alpha = 1023 on
ALPHA_MAX = 1022.0


def check_alpha(cfg):
    """ConfigError when contact_quadrature: exact cannot integrate [u]_+^alpha (ALPHA_MAX), before any solve."""
    if cfg.contact_quadrature != "exact":  # (a signorini study refuses alpha: its default passes)
        return
    for path, values in (("alpha", (cfg.alpha,)), ("limit.alpha", cfg.limit.alpha if cfg.limit else ())):
        for alpha in values:
            if alpha > ALPHA_MAX:
                raise ConfigError(path, f"{alpha:g} is above {ALPHA_MAX:g}, the largest alpha contact_quadrature: "
                                        "exact integrates (its Gauss-Jacobi weights carry 2^-(alpha+1)); use "
                                        "contact_quadrature: vertex or a Gauss degree")


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


def positive_power(comm, values, points, beta, degree=1):
    """∫_Γc [w_h]_+^beta over the rank's owned Γ_C facets, summed over ranks, of the facet dof values
    (facets, k) of a function of `degree` at the facets' dof points (facets, k, 3): P1 in closed form (the
    solve's own rule), P2 with each facet cut at the zeros of its quadratic (kinked.on_facets)."""
    if not len(values):
        local = 0.0
    elif degree == 1:
        local = float(np.sum(measure.facet_sizes(points) * moments(values, beta)[0]))
    else:
        trace = measure.on_facets(values)
        local = float(np.sum(kinked.on_facets(measure.vertices(points, degree), lambda *a: psi(trace[0](*a), beta),
                                              [trace])))
    return comm.allreduce(local, op=MPI.SUM)


# --- the kinked data term (1/eps)∫_Γc [u_ex]_+^alpha v: adaptive rules around the zeros of u_ex ------

ZERO_ULPS = 64  # |u_ex| <= 64 ulp of its scale is a zero: sin(pi) evaluates to 1.2e-16, not 0


def snap_zeros(u_fn, points):
    """u_fn with values within ZERO_ULPS round-off of zero (scale: max |u_ex| at the facets' vertices) set
    to 0, so a zero of u_ex on a vertex is a zero to the sign tests (and gets the Gauss-Jacobi piece its
    kink needs) whichever side of 0 its round-off fell."""
    with np.errstate(all="ignore"):
        scale = float(np.max(np.abs(u_fn(points)), initial=0.0))
    tol = ZERO_ULPS * np.finfo(float).eps * scale

    def snapped(x):
        u = np.asarray(u_fn(x), dtype=float)
        return np.where(np.abs(u) <= tol, 0.0, u)
    return snapped


SIGN_SAMPLES = 4  # sub-intervals per line (lattice divisions per triangle) searched for sign changes of u_ex
GAUSS_POINTS = 10  # Gauss-Legendre / Gauss-Jacobi points per piece (make the test: 1e-12 on facets of h <= 0.1)
ZERO_ITERATIONS = 40  # Illinois steps locating a zero of u_ex in a sub-interval where it changes sign


def data_segments(u_fn, alpha, starts, ends, weights_fn, samples=SIGN_SAMPLES):
    """∫_0^1 [u(x(t))]_+^alpha w dt on the segments x(t) = start + t (end - start), shapes (M, 3), with
    the vector weights w = weights_fn(rows, t) (P, points, k) of the segments `rows`: (M, k). Each of
    `samples` sub-intervals is integrated by Gauss-Legendre where u > 0 at both ends and, where u
    changes sign, cut at its zero and integrated by Gauss-Jacobi with the weight |t - zero|^alpha, so
    that the kink of [.]_+^alpha costs no accuracy."""
    grid = np.linspace(0.0, 1.0, samples + 1)
    u = _on_segments(u_fn, starts, ends, np.broadcast_to(grid, (len(starts), grid.size)))
    rows = np.broadcast_to(np.arange(len(starts))[:, None], (len(starts), samples))
    lo, hi = np.broadcast_to(grid[:-1], rows.shape), np.broadcast_to(grid[1:], rows.shape)
    plus_lo, plus_hi = u[:, :-1] > 0, u[:, 1:] > 0
    smooth, change = plus_lo & plus_hi, plus_lo != plus_hi
    total = np.zeros((len(starts), 0))
    pieces = [(rows[smooth], lo[smooth], hi[smooth], None)]
    if change.any():
        r = rows[change]
        zero = _zero(u_fn, starts[r], ends[r], lo[change], hi[change], u[:, :-1][change], u[:, 1:][change])
        pieces.append((r, zero, np.where(plus_lo[change], lo[change], hi[change]), alpha))  # to the positive end
    for r, origin, end, jacobi in pieces:
        values = _pieces(u_fn, alpha, starts[r], ends[r], lambda t: weights_fn(r, t), origin, end, jacobi)
        if not total.size:
            total = np.zeros((len(starts), values.shape[1]))
        np.add.at(total, r, values)
    return total


def _on_segments(u_fn, starts, ends, t):
    """u at the parameters t (M, q) of the segments."""
    points = starts[:, None, :] + t[..., None] * (ends - starts)[:, None, :]
    return np.broadcast_to(u_fn(points), t.shape)


def _zero(u_fn, starts, ends, lo, hi, u_lo, u_hi):
    """The zero of u in [lo, hi] of each segment, where u_lo > 0 >= u_hi or the reverse (kinked.illinois)."""
    along = ends - starts

    def u_at(t, which):
        return np.broadcast_to(u_fn(starts[which] + t[:, None] * along[which]), t.shape)
    return kinked.illinois(u_at, lo, hi, u_lo, u_hi, ZERO_ITERATIONS)


def _pieces(u_fn, alpha, starts, ends, weights_fn, origin, end, jacobi):
    """∫ [u]_+^alpha w dt over the pieces [origin, end] (P,) of the segments (P, 3): Gauss-Legendre
    (jacobi None) or Gauss-Jacobi with the weight |t - origin|^alpha, u vanishing at the origin."""
    if jacobi is None:
        x, w = special.roots_legendre(GAUSS_POINTS)
        s, w = (x + 1) / 2, w / 2
    else:
        x, w = special.roots_jacobi(GAUSS_POINTS, 0.0, jacobi)
        s, w = (x + 1) / 2, w / 2 ** (jacobi + 1)  # ∫_0^1 s^alpha f(s) ds
    length = end - origin  # signed: the piece may run backwards from its zero
    t = origin[:, None] + length[:, None] * s  # (P, points)
    u = _on_segments(u_fn, starts, ends, t)
    values = psi(u, alpha) if jacobi is None else psi(u / s, alpha)  # (u/s)^alpha s^alpha = u^alpha
    return np.einsum("pq,pqk,q,p->pk", values, weights_fn(t), w, np.abs(length))


def data_on_segments(u_fn, alpha, points):
    """∫_S [u]_+^alpha lambda_i on segments given as (facets, 2, 3) vertex points: (facets, 2)."""
    def weights(rows, t):
        return np.stack((1 - t, t), axis=-1)
    lengths = np.linalg.norm(points[:, 1] - points[:, 0], axis=1)
    return lengths[:, None] * data_segments(u_fn, alpha, points[:, 0], points[:, 1], weights)


def data_on_triangles(u_fn, alpha, points):
    """∫_T [u]_+^alpha lambda_i on triangles (facets, 3, 3): collapsed coordinates x = P0 + a e1 + b e2,
    b = t (1 - a); lines of fixed a by data_segments, and in a Gauss-Legendre on the pieces between the
    zeros of u on the edges b = 0 and a + b = 1 (where the inner integral stops being smooth in a).
    Triangles with u > 0 on their whole sample lattice take one piece each way, with u <= 0 none."""
    p0, e1, e2 = points[:, 0], points[:, 1] - points[:, 0], points[:, 2] - points[:, 0]
    lattice = np.array([(i, j) for i in range(SIGN_SAMPLES + 1) for j in range(SIGN_SAMPLES + 1 - i)]) / SIGN_SAMPLES
    u = u_fn(p0[:, None] + lattice[None, :, :1] * e1[:, None] + lattice[None, :, 1:] * e2[:, None])
    u = np.broadcast_to(u, (len(points), len(lattice)))
    smooth = (u > 0).all(axis=1)
    kinked = (u > 0).any(axis=1) & ~smooth
    result = np.zeros((len(points), 3))
    for mask, samples in ((smooth, 1), (kinked, SIGN_SAMPLES)):
        if mask.any():
            result[mask] = _triangle_lines(u_fn, alpha, p0[mask], e1[mask], e2[mask], samples)
    areas = np.linalg.norm(np.cross(e1, e2), axis=1) / 2
    return 2 * areas[:, None] * result


def _triangle_lines(u_fn, alpha, p0, e1, e2, samples):
    """∫_0^1 (1-a) ∫_0^1 [u]_+^alpha lambda dt da (collapsed coordinates) on the given triangles."""
    breaks = _outer_breakpoints(u_fn, p0, e1, e2, samples)  # (M, B) sorted
    lo, hi = breaks[:, :-1], breaks[:, 1:]
    tri = np.broadcast_to(np.arange(len(p0))[:, None], lo.shape)[hi > lo]  # the pieces of positive length
    lo, hi = lo[hi > lo], hi[hi > lo]
    x, w = special.roots_legendre(GAUSS_POINTS)
    s = (x + 1) / 2
    # where the zero of u leaves through an edge the inner integral behaves like |a - a*|^(alpha+1):
    # a = lo + (hi - lo) s^2 (3 - 2s) flattens both ends of each piece
    a = (lo[:, None] + (hi - lo)[:, None] * s**2 * (3 - 2 * s)).reshape(-1)  # one line per outer point
    weight = ((hi - lo)[:, None] * w / 2 * 6 * s * (1 - s)).reshape(-1) * (1 - a)
    line_tri = np.repeat(tri, GAUSS_POINTS)
    starts = p0[line_tri] + a[:, None] * e1[line_tri]
    ends = starts + (1 - a)[:, None] * e2[line_tri]

    def weights(rows, t):  # lambda_0, lambda_1, lambda_2 = 1 - a - b, a, b with b = t (1 - a)
        a_t = np.broadcast_to(a[rows][:, None], t.shape)
        b = t * (1 - a_t)
        return np.stack((1 - a_t - b, a_t, b), axis=-1)

    lines = data_segments(u_fn, alpha, starts, ends, weights, samples)
    result = np.zeros((len(p0), 3))
    np.add.at(result, line_tri, weight[:, None] * lines)
    return result


def _outer_breakpoints(u_fn, p0, e1, e2, samples):
    """0, 1 and, with samples > 1, the zeros of u along the edges b = 0 (P0 -> P1) and a + b = 1
    (P2 -> P1), both parametrised by a (one per sample sub-interval where u changes sign, else 0)."""
    found = [np.zeros((len(p0), 1)), np.ones((len(p0), 1))]
    if samples > 1:
        grid = np.linspace(0.0, 1.0, samples + 1)
        for start, end in ((p0, p0 + e1), (p0 + e2, p0 + e1)):
            u = _on_segments(u_fn, start, end, np.broadcast_to(grid, (len(p0), grid.size)))
            change = (u[:, :-1] > 0) != (u[:, 1:] > 0)
            zeros = np.zeros(change.shape)
            rows = np.broadcast_to(np.arange(len(p0))[:, None], change.shape)[change]
            lo, hi = np.broadcast_to(grid[:-1], change.shape)[change], np.broadcast_to(grid[1:], change.shape)[change]
            zeros[change] = _zero(u_fn, start[rows], end[rows], lo, hi, u[:, :-1][change], u[:, 1:][change])
            found.append(zeros)
    return np.sort(np.concatenate(found, axis=1), axis=1)


# --- assembly beside the UFL forms ----------------------------------------------------------------------

RULES = ("exact", "vertex")


class ContactTerm:
    """(1/eps)∫_Γc [w_h]_+^alpha v (penalty) minus (1/eps)∫_Γc [w_ex]_+^alpha v (data) on the rank's owned
    Γ_C facets (each counted once under MPI), integrated by `rule`: exact (the P1 integrals in closed
    form, the data by adaptive rules) or vertex (lumped: (1/eps) psi(w_i) ∫ lambda_i). On a scalar space
    w = u; on a vector space w = u·n − g0 with `normal` (facets, d), constant per facet, and `gap` g0 taken
    at the facets' vertices (gap(points) of the (facets, n+1, 3) points), so that w_h is linear on each facet
    and the same rules are exact;
    the test function is then v·n. `penalty` False leaves the penalty to UFL (the smooth positive part);
    `u_exact(points, eps)` evaluates w_ex in numpy (None: no kinked data term). `eps` is the forms'
    Constant, read at every evaluation."""

    def __init__(self, u_h, facet_tags, marker, alpha, eps, rule="exact", penalty=True, u_exact=None,
                 normal=None, gap=None):
        self.u_h = u_h  # the iterate: the solver keeps it in u_h (ghosts updated) when it assembles
        self.dofs, self.points = measure.contact_facet_dofs(u_h.function_space, facet_tags, marker)
        self.sizes = measure.facet_sizes(self.points)
        self.alpha, self.eps, self.rule, self.penalty, self.u_exact = alpha, eps, rule, penalty, u_exact
        self.bs = u_h.function_space.dofmap.index_map_bs
        self.degree = element.degree_of(u_h.function_space)
        self.normal = normal
        self.gap = np.zeros(self.dofs.shape) if gap is None else np.broadcast_to(gap(self.points), self.dofs.shape)
        self._data, self._data_eps = None, None

    @property
    def rows(self):
        """The local dof indices the term touches, (facets, (n+1) bs): vertex-major, component-minor."""
        rows = self.bs * self.dofs[:, :, None] + np.arange(self.bs)
        return rows.reshape(len(self.dofs), self.dofs.shape[1] * self.bs)

    def values(self, u):
        """w at the facets' vertices (facets, n+1) from the local array u: u itself, or u·n − g0."""
        if self.normal is None:
            return u[self.dofs]
        return np.einsum("fvk,fk->fv", u.reshape(-1, self.bs)[self.dofs], self.normal) - self.gap

    def prepare(self):
        """The data term at the current eps, computed once per eps (once per SNES solve)."""
        eps = float(self.eps.value)
        if self.u_exact is None or self._data_eps == eps:
            return
        u_fn = snap_zeros(lambda x: self.u_exact(x, eps), self.points)
        if self.rule == "vertex":
            self._data = self.sizes[:, None] / self.dofs.shape[1] * psi(u_fn(self.points), self.alpha)
        elif self.degree == 2:
            self._data = p2_integrals(self.points, lambda facets, x: u_fn(x), self.alpha, 1)
        else:
            rule = data_on_segments if self.dofs.shape[1] == 2 else data_on_triangles
            self._data = canonical(rule, u_fn, self.alpha, self.points)
        self._data_eps = eps

    def residual(self, u):
        """Per facet and vertex (facets, n+1): the term's residual at the P1 values u (local array)."""
        values = np.zeros(self.dofs.shape)
        if self.penalty:
            u_f = self.values(u)
            if self.rule == "vertex":
                values += self.sizes[:, None] / u_f.shape[1] * psi(u_f, self.alpha)
            elif self.degree == 2:
                values += p2_integrals(self.points, u_f, self.alpha, 1)
            else:
                values += self.sizes[:, None] * moments(u_f, self.alpha)[1]
        if self.u_exact is not None:
            self.prepare()
            values -= self._data
        return values / float(self.eps.value)

    def jacobian(self, u):
        """Per facet (facets, n+1, n+1): (1/eps)∫ alpha [w_h]_+^(alpha-1) lambda_i lambda_j (vertex: diagonal)."""
        u_f = self.values(u)
        k = u_f.shape[1]
        if self.rule == "vertex":
            diagonal = self.sizes[:, None] / k * self.alpha * psi(u_f, self.alpha - 1)
            values = diagonal[:, :, None] * np.eye(k)
        elif self.degree == 2:
            values = self.alpha * p2_integrals(self.points, u_f, self.alpha - 1, 2)
        else:
            values = self.sizes[:, None, None] * self.alpha * moments(u_f, self.alpha - 1)[2]
        return values / float(self.eps.value)

    def add_residual(self, b):
        """b += the residual at u_h (local array, ghosts included: before b's reverse ghost update)."""
        r = self.residual(self.u_h.x.array)
        if self.normal is not None:  # the test function's normal component: r_i n_k at dof (i, k)
            r = (r[:, :, None] * self.normal[:, None, :]).reshape(self.rows.shape)
        np.add.at(b, self.rows, r)

    def add_jacobian(self, A, fixed):
        """A += the Jacobian (ADD, local indices) off the rows and columns of the local dofs `fixed`
        (bool mask: Dirichlet dofs, whose identity rows the solver set). Collective."""
        if not self.penalty:
            return
        A.assemblyBegin(PETSc.Mat.AssemblyType.FLUSH)  # after the INSERTed identity rows of Γ_D
        A.assemblyEnd(PETSc.Mat.AssemblyType.FLUSH)
        if len(self.dofs):  # (petsc4py divides by the number of blocks)
            rows = self.rows
            index = np.where(fixed[rows], -1, rows).astype(PETSc.IntType)  # PETSc skips index -1
            A.setValuesLocalRCV(index, index, self.block_jacobian(self.u_h.x.array), addv=PETSc.InsertMode.ADD)

    def block_jacobian(self, u):
        """The Jacobian per facet on the term's rows: J_ij, or J_ij n_k n_l on a vector space."""
        J = self.jacobian(u)
        if self.normal is None:
            return J
        nn = self.normal[:, :, None] * self.normal[:, None, :]  # (facets, d, d)
        blocks = J[:, :, None, :, None] * nn[:, None, :, None, :]  # (facets, i, k, j, l)
        size = J.shape[1] * self.bs
        return blocks.reshape(len(J), size, size)


def p2_integrals(points, w, beta, order):
    """∫_F [w]_+^beta phi_i (order 1: (facets, k)) or ∫_F [w]_+^beta phi_i phi_j (order 2: (facets, k, k)) on
    the P2 facets F (dof points (facets, k, 3): vertices, then the edges' midpoints; k = 3 on segments, 6 on
    triangles), w the P2 trace's dof values (facets, k) or an expression w(facets, x): each facet cut at the
    zeros of w (the quadratic's in closed form), tanh-sinh on each piece (kinked.on_facets)."""
    trace = measure.on_facets(w)

    def integrand(facets, lam, x):
        phi = measure.p2_basis(lam)
        value = psi(trace[0](facets, lam, x), beta)[..., None] * phi
        return value if order == 1 else value[..., None] * phi[..., None, :]
    return kinked.on_facets(np.ascontiguousarray(measure.vertices(points, 2)), integrand, [trace])


def canonical(rule, u_fn, alpha, points):
    """rule(u_fn, alpha, points) with each facet's vertices in lexicographic order of their coordinates,
    its (facets, n+1) result put back in the facet's own order: the adaptive rules start from a facet's first
    vertex, and they agree with themselves to ~1e-12 only, so a facet numbered otherwise (on another
    partition) would otherwise give other round-off."""
    order = np.lexsort(np.moveaxis(points, -1, 0)[::-1], axis=-1)  # (facets, n+1): by x, then y, then z
    sorted_values = rule(u_fn, alpha, np.take_along_axis(points, order[..., None], axis=1))
    values = np.empty_like(sorted_values)
    np.put_along_axis(values, order, sorted_values, axis=1)
    return values
