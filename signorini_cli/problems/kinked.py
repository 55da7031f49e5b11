"""Integrals over Γ_C facets of integrands that kink inside them ([u]_+, |[u]_+ − [u_h]_+|^(α+1)): each facet
is cut where a kink function changes sign (closed form for polynomials along the cut, else a bracketed zero),
and each smooth piece is integrated by a double-exponential (tanh-sinh) rule, whose nodes crowd towards the
piece's ends: an end where the integrand is only C^p (|t − t0|^p) costs it no accuracy."""
from typing import NamedTuple

import numpy as np

# tanh-sinh: t = (1 + tanh(π/2 sinh s))/2, s in [-RANGE, RANGE] by STEP; at s = ±RANGE the weight is 1e-17
# of the piece, and the rule's error for a piece analytic inside is below 1e-15 from STEP = 1/8 on (halving
# STEP to 1/16 changes the integrals of tests/problems/test_kinked.py by less than 1e-15 relative)
STEP = 1 / 8
RANGE = 3.15
CHUNK = 2048  # pieces integrated at once (their nodes' points and values: a few MB)
ZERO_ITERATIONS = 60  # Illinois steps locating such a zero in a sub-interval where it changes sign


class Search(NamedTuple):
    """How the zeros of a kink function that is no polynomial are found: its signs at `samples` sub-intervals
    of each cut, its zero curve's tangents to the lines on quadratic interpolants over triangles of size
    2/seeds covering the facet (refined around each one found)."""
    samples: int
    seeds: int


# by the degree of the discrete trace in u − u_h: that of a P2 trace has pairs of zeros closer than 1/8 of a
# cut and curves with several branches per facet (8 and 4 left pos_gc 4e-13 off on test_kinked.py's P2
# face); for a P1 trace 16 and 4 give the 3-D cube study's pos_gc of 32 and 8 to 6e-16 (N = 8, 16, 32) at
# half the cost, and that of 128 and 16 (with STEP / 4) to the last digit (N = 4, 8, 12)
SEARCH = {1: Search(16, 4), 2: Search(32, 8)}


def tanh_sinh():
    """Nodes and weights of the tanh-sinh rule on [0, 1]: ∫_0^1 f ≈ Σ w f(t)."""
    s = np.arange(-RANGE, RANGE + STEP / 2, STEP)
    v = np.pi / 2 * np.sinh(s)
    t = 1 / (1 + np.exp(-2 * v))  # (1 + tanh v)/2, accurate near both ends
    w = STEP * np.pi / 4 * np.cosh(s) / np.cosh(v) ** 2
    return t, w


NODES, WEIGHTS = tanh_sinh()


class Cuts:
    """Straight cuts through facets: from barycentric coordinates lam0 to lam1 (M, n+1) and points x0 to x1
    (M, 3), each cut belonging to the facet `facet` (M,)."""

    def __init__(self, facet, lam0, lam1, x0, x1):
        self.facet, self.k = facet, lam0.shape[1]
        # lam and x side by side: one array op for both, the most frequent one of the rule
        self.start, self.step = np.hstack((lam0, x0)), np.hstack((lam1 - lam0, x1 - x0))

    def at(self, rows, t):
        """(facets, lam, x) at the parameters t (P, q) of the cuts `rows` (P,)."""
        both = t[..., None] * self.step[rows, None]
        both += self.start[rows, None]
        return self.facet[rows], both[..., :self.k], both[..., self.k:]


def integrate(cuts, integrand, kinks):
    """∫_0^1 integrand dt along each cut, (M, ...): integrand(facets, lam, x) -> (P, q, ...); the cut
    split at the zeros of every kink function k(facets, lam, x) -> (P, q), given as (k, search): a
    polynomial of degree <= 2 along the cut (search None) has its zeros in closed form, any other is
    bracketed on search.samples sub-intervals (two zeros closer than one sub-interval may go unseen: their
    integrand is as small as the function between them)."""
    rows, lo, width = _pieces(_breaks([cuts], kinks))
    total = None
    for start in range(0, max(len(rows), 1), CHUNK):  # in chunks: the temporaries stay in cache
        piece = slice(start, start + CHUNK)
        t = lo[piece, None] + width[piece, None] * NODES
        values = integrand(*cuts.at(rows[piece], t))
        found = np.einsum("pq...,q,p->p...", values, WEIGHTS, width[piece])
        if total is None:
            total = np.zeros((len(cuts.facet),) + found.shape[1:])
        np.add.at(total, rows[piece], found)
    return total


def _breaks(cuts_list, kinks):
    """0, 1 and the zeros of every kink along each of the cuts (all with the same rows): (M, B) sorted,
    nan (no zero) last."""
    m = len(cuts_list[0].facet)
    breaks = [np.zeros((m, 1)), np.ones((m, 1))]
    for cuts in cuts_list:
        for kink, search in kinks:
            breaks.append(_zeros(cuts, kink, search))
    return np.sort(np.concatenate(breaks, axis=1), axis=1)


def _pieces(breaks):
    """(rows, lo, width): the pieces of positive width between successive breaks, their starts and widths
    (P,); their tanh-sinh nodes are lo + width * NODES."""
    lo, hi = breaks[:, :-1], breaks[:, 1:]
    piece = hi > lo  # False for nan
    rows = np.broadcast_to(np.arange(len(breaks))[:, None], lo.shape)[piece]
    lo, hi = lo[piece], hi[piece]
    return rows, lo, hi - lo


def _zeros(cuts, kink, search):
    """The kink's zeros along each cut (M, Z), nan for none: in closed form for a polynomial (search None)."""
    return _quadratic_zeros(cuts, kink) if search is None else _bracketed_zeros(cuts, kink, search.samples)


def _quadratic_zeros(cuts, kink):
    """The zeros in (0, 1) of the quadratic through the kink's values at t = 0, 1/2, 1: (M, 2), nan if none."""
    m = len(cuts.facet)
    return _roots(kink(*cuts.at(np.arange(m), np.broadcast_to([0.0, 1.0, 0.5], (m, 3)))))


def _roots(p):
    """The zeros in (0, 1) of the quadratics through the values p (M, 3) at t = 0, 1, 1/2: (M, 2), nan if none."""
    a, b, c = p[:, 0], 4 * p[:, 2] - 3 * p[:, 0] - p[:, 1], 2 * p[:, 0] + 2 * p[:, 1] - 4 * p[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        disc = b**2 - 4 * a * c
        q = -(b + np.copysign(np.sqrt(np.where(disc >= 0, disc, np.nan)), b)) / 2  # no cancellation
        roots = np.stack((q / c, a / q), axis=1)  # c ~ 0 (a line): q / c leaves [0, 1], a / q is its zero
    return np.where((roots > 0) & (roots < 1), roots, np.nan)


def _bracketed_zeros(cuts, kink, samples):
    """The zeros of kink along each cut, one per sub-interval of `samples` where it changes sign: (M, samples)."""
    m = len(cuts.facet)
    grid = np.linspace(0.0, 1.0, samples + 1)
    k = np.empty((m, samples + 1))
    for start in range(0, m, CHUNK):  # in chunks: the cuts' points stay in cache
        rows = np.arange(start, min(start + CHUNK, m))
        k[rows] = kink(*cuts.at(rows, np.broadcast_to(grid, (len(rows), len(grid)))))
    change = (k[:, :-1] > 0) != (k[:, 1:] > 0)
    zeros = np.full(change.shape, np.nan)
    rows = np.broadcast_to(np.arange(m)[:, None], change.shape)[change]
    lo, hi = (np.broadcast_to(ends, change.shape)[change] for ends in (grid[:-1], grid[1:]))
    zeros[change] = illinois(lambda t, which: kink(*cuts.at(rows[which], t[:, None]))[:, 0], lo, hi,
                             k[:, :-1][change], k[:, 1:][change])
    return zeros


def illinois(f, lo, hi, f_lo, f_hi, iterations=ZERO_ITERATIONS):
    """The zero of f in each bracket [lo, hi] (B,), where f_lo > 0 >= f_hi or the reverse (f(t, which) -> the
    values at the parameters t of the brackets `which`): regula falsi with the Illinois modification
    (superlinear; the bracket always holds the zero). A bracket stops when no float lies inside it or f is 0."""
    lo, hi, f_lo, f_hi = (np.array(v, dtype=float) for v in (lo, hi, f_lo, f_hi))
    which = np.arange(len(lo))
    for _ in range(iterations):
        a, b, f_a, f_b = lo[which], hi[which], f_lo[which], f_hi[which]
        with np.errstate(invalid="ignore", divide="ignore"):
            t = np.where(f_b != f_a, (a * f_b - b * f_a) / (f_b - f_a), (a + b) / 2)
        t = np.clip(t, np.minimum(a, b), np.maximum(a, b))
        f_t = f(t, which)
        same = (f_t > 0) == (f_a > 0)
        lo[which], f_lo[which] = np.where(same, t, a), np.where(same, f_t, f_a / 2)
        hi[which], f_hi[which] = np.where(same, b, t), np.where(same, f_b / 2, f_t)
        low, high = np.minimum(lo[which], hi[which]), np.maximum(lo[which], hi[which])
        which = which[(f_t != 0) & (np.nextafter(low, high) < high)]  # a float strictly inside: not done
        if not len(which):
            break
    return np.where(np.abs(f_lo) <= np.abs(f_hi), lo, hi)


TANGENT_SIZES = (1 / 4, 1 / 16, 1 / 64, 1 / 256, 1 / 1024)  # then around each one found, in facet units
NEAR = 0.5  # a complex tangent point this near the real a axis (facet units) makes a break at its real part
LINEAR_B = 1e-12  # |c5| below this share of a kink's values: linear along the lines (round-off of a P1 trace)
# the P2 nodes of a triangle in barycentric coordinates: its vertices, then the midpoints of the edges
# opposite vertex 0, 1, 2 (the order of a facet's closure dofs, measure.contact_facet_dofs)
P2_NODES = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0.5, 0.5], [0.5, 0, 0.5], [0.5, 0.5, 0]])


def triangle_coefficients(values):
    """(c0 .. c5) of w = c0 + c1 a + c2 b + c3 a² + c4 ab + c5 b², (a, b) = (lam_1, lam_2), through the values
    (M, 6) at P2_NODES."""
    v0, v1, v2, m0, m1, m2 = values.T
    c1, c3 = 4 * m2 - 3 * v0 - v1, 2 * v0 + 2 * v1 - 4 * m2  # along b = 0
    c2, c5 = 4 * m1 - 3 * v0 - v2, 2 * v0 + 2 * v2 - 4 * m1  # along a = 0
    c4 = 4 * (m0 - v0) - 2 * (c1 + c2) - c3 - c5  # at the midpoint (1/2, 1/2)
    return v0, c1, c2, c3, c4, c5


def _tangents(points, kink, search):
    """The positions a (M, T) where a kink's zero curve is tangent to the lines of fixed a (the lines of
    on_facets, along e2 = P2 − P0), nan if none: there ∂w/∂b = 0 and w = 0, and the integral along the line
    has a square-root kink in a. Found on the kink's quadratic interpolant over the facet, exact for a
    quadratic kink; any other is interpolated over triangles of size 2/search.seeds covering the facet (its zero set
    may have more branches than one conic's), and each point found again on the interpolants over triangles
    TANGENT_SIZES around it (the interpolant's error falls as the size cubed). With them, the real parts of
    near complex tangent points (_quadratic_tangents). A kink linear in b to round-off (every P1 trace) has none."""
    m = len(points)
    origins, size = (np.zeros((1, 2)), 1.0) if search is None else _seeds(search.seeds)
    facets = np.repeat(np.arange(m), len(origins))
    a, b, near = _quadratic_tangents(points, kink, facets, np.tile(origins, (m, 1)).T, size)
    facets, a, b = np.repeat(facets, 2), a.ravel(), b.ravel()
    for size in () if search is None else TANGENT_SIZES:
        found = np.flatnonzero(np.isfinite(a) & np.isfinite(b))
        a_near, b_near, _ = _quadratic_tangents(points, kink, facets[found],
                                                np.stack((a[found], b[found])) - size / 3, size)
        distance = np.nan_to_num((a_near - a[found, None]) ** 2 + (b_near - b[found, None]) ** 2, nan=np.inf)
        closest = distance.argmin(axis=1)[:, None]
        moved = np.isfinite(np.take_along_axis(distance, closest, axis=1)[:, 0])  # else: keep the last point
        a[found[moved]] = np.take_along_axis(a_near, closest, axis=1)[moved, 0]
        b[found[moved]] = np.take_along_axis(b_near, closest, axis=1)[moved, 0]
    inside = (a > 0) & (a < 1) & (b >= 0) & (b <= 1 - a)
    return np.hstack((np.where(inside, a, np.nan).reshape(m, 2 * len(origins)), near.reshape(m, len(origins))))


def _seeds(n):
    """(origins (T, 2), size): the triangles of size 2/n at (i, j)/n, i + j <= n - 2, covering the facet."""
    return np.array([(i, j) for i in range(n - 1) for j in range(n - 1 - i)]) / n, 2 / n


def _quadratic_tangents(points, kink, facets, origin, size):
    """(a, b, near): the points (a, b), each (F, 2), where the zero curve of the kink's quadratic interpolant
    over the triangle origin + size (P2_NODES' a, b) of the facets is tangent to a line of fixed a, nan if none;
    near (F,), the real part of a complex tangent point within NEAR of the real a axis, nan if none (two
    branches of a conic passing close: the integral along the lines stays analytic in a, but with a
    singularity so near that the rule converges slowly unless the nearest real point is a piece's end).
    Tangent where the discriminant D(a) = (c2 + c4 a)² − 4 c5 (c0 + c1 a + c3 a²) of w in b vanishes."""
    a_nodes = origin[0][:, None] + size * P2_NODES[:, 1]
    b_nodes = origin[1][:, None] + size * P2_NODES[:, 2]
    lam = np.stack((1 - a_nodes - b_nodes, a_nodes, b_nodes), axis=2)
    values = kink(facets, lam, np.einsum("fqk,fkx->fqx", lam, points[facets]))
    c0, c1, c2, c3, c4, c5 = triangle_coefficients(values)
    c5 = np.where(np.abs(c5) > LINEAR_B * np.abs(values).max(axis=1), c5, np.nan)
    d2, d1, d0 = c4**2 - 4 * c5 * c3, 2 * c2 * c4 - 4 * c5 * c1, c2**2 - 4 * c5 * c0
    with np.errstate(divide="ignore", invalid="ignore"):
        zeros = _roots(np.nan_to_num(np.stack((d0, d0 + d1 + d2, d0 + d1 / 2 + d2 / 4), axis=1)))
        zeros[~np.isfinite(c5)] = np.nan
        b_zero = -(c2[:, None] + c4[:, None] * zeros) / (2 * c5[:, None])
        real, imaginary = -d1 / (2 * d2), np.sqrt(4 * d2 * d0 - d1**2) / (2 * np.abs(d2))
    near = np.where((size * imaginary <= NEAR) & (real > 0) & (real < 1), origin[0] + size * real, np.nan)
    return origin[0][:, None] + size * zeros, origin[1][:, None] + size * b_zero, near


def _crossings(points, kinks):
    """The positions a (M, C) where the zero line of a kink linear on the facet (a P1 trace) meets the zero
    curve of another kink, nan if none: there two kinks' zeros swap order along the lines of fixed a, and the
    integral along a line kinks in a. The zero line runs between the two edges where the kink changes sign."""
    m = len(points)
    found = [np.full((m, 0), np.nan)]
    for i, (line, search) in enumerate(kinks):
        if search is not None:
            continue
        values = _at_p2_nodes(points, line)
        coefficients = np.stack(triangle_coefficients(values)[3:], axis=1)
        linear = np.abs(coefficients).max(axis=1) <= LINEAR_B * np.abs(values).max(axis=1)
        ends = [edge_zero(points, values, p, q) for p, q in ((0, 1), (1, 2), (0, 2))]
        crossed = np.stack([np.isfinite(lam[:, 0]) for lam, _ in ends], axis=1)
        rows = np.flatnonzero(linear & (crossed.sum(axis=1) == 2))
        if not len(rows):
            continue
        first, second = np.argmax(crossed[rows], axis=1), 2 - np.argmax(crossed[rows, ::-1], axis=1)
        lam = np.stack([lam for lam, _ in ends], axis=1)[rows]  # (R, 3 edges, 3)
        x = np.stack([x for _, x in ends], axis=1)[rows]
        pick = np.arange(len(rows))
        cuts = Cuts(rows, lam[pick, first], lam[pick, second], x[pick, first], x[pick, second])
        for other, other_search in kinks[:i] + kinks[i + 1:]:
            t = _zeros(cuts, other, other_search)
            a = np.full((m, t.shape[1]), np.nan)
            a[rows] = cuts.start[:, None, 1] + t * cuts.step[:, None, 1]  # lam_1 along the cut
            found.append(a)
    return np.concatenate(found, axis=1)


def edge_zero(points, values, p, q):
    """(lam, x), each (M, k), (M, dim), of the zero of the facets' linear function with `values` at their
    vertices (points (M, k, dim)) on the edge from vertex p to vertex q, nan where it does not change sign there."""
    v_p, v_q = values[:, p], values[:, q]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where((v_p > 0) != (v_q > 0), v_p / (v_p - v_q), np.nan)
    eye = np.eye(points.shape[1])
    lam = (1 - t)[:, None] * eye[p] + t[:, None] * eye[q]
    return lam, np.einsum("mk,mkx->mx", lam, points)


def _at_p2_nodes(points, kink):
    """The kink's values (M, 6) at the facets' P2_NODES."""
    m = len(points)
    lam = np.broadcast_to(P2_NODES, (m, 6, 3))
    return kink(np.arange(m), lam, np.einsum("mqk,mkx->mqx", lam, points))


def on_facets(points, integrand, kinks):
    """∫_F integrand over each facet F (segments or triangles, points (M, n+1, 3)), kinks as integrate's.
    Triangles by collapsed coordinates x = P0 + a e1 + b e2, b = t (1 - a): the lines of fixed a by
    integrate, and in a by the same rule between the zeros of the kinks along the edges b = 0 and
    a + b = 1 (where a kink's curve leaves a line through its end, the integral along it kinks in a), where
    a kink's curve is tangent to a line (_tangents) and where a P1 trace's zero line crosses another kink's
    curve (_crossings). Where a P2 trace's conic crosses another kink's curve the integrand vanishes to higher
    order: splitting there too changed the P2 elastic cube's pos_gc by less than 1e-16."""
    m, k = points.shape[:2]
    facet, eye = np.arange(m), np.broadcast_to(np.eye(k), (m, k, k))
    if k == 2:
        lengths = np.linalg.norm(points[:, 1] - points[:, 0], axis=1)
        found = integrate(Cuts(facet, eye[:, 0], eye[:, 1], points[:, 0], points[:, 1]), integrand, kinks)
        return found * lengths.reshape((m,) + (1,) * (found.ndim - 1))
    edges = [Cuts(facet, eye[:, 0], eye[:, 1], points[:, 0], points[:, 1]),
             Cuts(facet, eye[:, 2], eye[:, 1], points[:, 2], points[:, 1])]
    breaks = [_breaks(edges, kinks), _crossings(points, kinks)] + [_tangents(points, kink, search)
                                                                   for kink, search in kinks]
    rows, lo, width = _pieces(np.sort(np.concatenate(breaks, axis=1), axis=1))
    a = lo[:, None] + width[:, None] * NODES  # (P, q): the lines' positions
    line_facet, a = np.repeat(rows, a.shape[1]), a.ravel()
    zero = np.zeros_like(a)
    e1, e2 = points[:, 1] - points[:, 0], points[:, 2] - points[:, 0]
    x0 = points[line_facet, 0] + a[:, None] * e1[line_facet]
    lines = Cuts(line_facet, np.stack((1 - a, a, zero), axis=1), np.stack((zero, a, 1 - a), axis=1),
                 x0, x0 + (1 - a)[:, None] * e2[line_facet])
    along = integrate(lines, integrand, kinks)  # (L, ...)
    weight = ((width[:, None] * WEIGHTS).ravel() * (1 - a)).reshape((-1,) + (1,) * (along.ndim - 1))
    found = np.zeros((m,) + along.shape[1:])
    np.add.at(found, line_facet, weight * along)
    areas = np.linalg.norm(np.cross(e1, e2), axis=1) / 2
    return 2 * found * areas.reshape((m,) + (1,) * (found.ndim - 1))
