"""Convergence rates: observed between levels, fitted over the last levels, proven by the paper
(Cantin & Hild 2020, one table of records), and the observed order, Richardson extrapolation and
grid convergence index of a scalar quantity (Roache; Celik et al. 2008). `slope` is the one log-log
least-squares fit of the package and its scripts (rates in h, in eps, costs in dofs)."""
import math
from dataclasses import dataclass

import numpy as np

from ..config import expressions

FIT_LEVELS = 3  # the last levels a rate is fitted over without a config (verification.fit_levels' default)


def observed(h, errors, valid):
    """Rates log(e_{k-1}/e_k)/log(h_{k-1}/h_k) against the previous valid level; None where undefined."""
    rates, previous = [], None
    for k, (h_k, e_k, ok) in enumerate(zip(h, errors, valid)):
        usable = ok and e_k is not None and e_k > 0
        if usable and previous is not None and h[previous] != h_k:
            rates.append(math.log(errors[previous] / e_k) / math.log(h[previous] / h_k))
        else:
            rates.append(None)
        previous = k if usable else previous
    return rates


def usable(values, valid):
    """Indices of the levels with a valid, positive value."""
    return [k for k, (v, ok) in enumerate(zip(values, valid)) if ok and v is not None and v > 0]


def error_columns(rows):
    """The measured norms of a table (rows of dicts): every column X that has a rate column rate_X,
    in table order (L2, H1, the Γ_C and reference norms)."""
    return [c for c in (rows[0] if rows else {}) if f"rate_{c}" in rows[0]]


def slope(x, y, k=FIT_LEVELS):
    """Least-squares slope of log y against log x over the last k points with x, y > 0 (None with fewer
    than two distinct x): the rate of e ~ h^p, of a model error in eps, of a cost in dofs."""
    points = [(a, b) for a, b in zip(x, y) if a is not None and b is not None and a > 0 and b > 0][-k:]
    if len({a for a, _ in points}) < 2:
        return None
    return regression(np.log([a for a, _ in points]), np.log([b for _, b in points]))[0]


def regression(log_x, log_y):
    """(slope, intercept, standard error of the slope: None with two points) of the least-squares line."""
    (p, c) = np.polyfit(log_x, log_y, 1)
    if len(log_x) < 3:
        return float(p), float(c), None
    residual = log_y - (p * log_x + c)
    sxx = float(np.sum((log_x - np.mean(log_x)) ** 2))
    return float(p), float(c), math.sqrt(float(np.sum(residual**2)) / (len(log_x) - 2) / sxx)


def fitted(h, errors, valid, k=FIT_LEVELS, log_factor=False):
    """Least-squares slope of log e against log h over the last k usable levels (None if fewer than 2).
    With log_factor the fit is of e/|ln h|: the slope that should reach p when e = O(h^p |ln h|)."""
    found = fit(h, errors, valid, k, log_factor)  # |ln h| vanishes at h = 1: such levels are left out
    return None if found is None else found.slope


# rates r(h) = p + c h^q + ... change by rho = 2^-q per halving of h: q = 1 gives 1/2, the demo's L2 shows
# 0.58-0.61; with one change known q is taken as Q_UNKNOWN (rho = 2/3 per halving: the rest of the way twice
# the last change), never below Q_MIN (rho = 3/4): rates that settle slower are called drifting by the
# interval's width. In h, not in levels, so that any refinement ratios (N = 8, 12, 16; gmsh sizes) extrapolate.
Q_UNKNOWN, Q_MIN, Q_MAX = math.log2(3 / 2), math.log2(4 / 3), 16.0
# the narrowest interval: errors whose constant drifts by 3 % over three levels (h / 4) move their fitted slope
# by ln(1.03)/ln(4) = 0.02, a change no pre-asymptotic study rules out (the demo's L2 constant e/h^2 drifts
# by 2.8 % over N = 32..128)
MIN_HALF = 0.02


@dataclass(frozen=True)
class Fit:
    """A fitted slope with its uncertainty: `se` the regression's standard error (None with 2 levels),
    `rates` the successive rates between the fitted levels. The interval [lo, hi] holds slope ± 2 se
    (~95 % for normal residuals, at least ± MIN_HALF), every successive rate of the fit and `limit`, where
    the rates head (with `log_approach` also `log_limit`, where they head if they approach it as 1/|ln h|)."""
    slope: float
    se: float
    rates: tuple
    levels: tuple  # indices of the fitted levels
    history: tuple = ()  # the successive rates of every usable level up to the last fitted one
    midpoints: tuple = ()  # the h each of them belongs to: sqrt(h_{k-1} h_k)
    log_approach: bool = False

    @property
    def limit(self):
        """Where the rates head: r(h) = p + c h^q through the last two rates, q from the last three (Q_UNKNOWN
        with fewer, or when their changes differ in sign; at least Q_MIN); p is the limit."""
        if len(self.history) < 2:
            return self.rates[-1]
        (m2, m3), (r2, r3) = self.midpoints[-2:], self.history[-2:]
        q = Q_UNKNOWN
        if len(self.history) > 2 and (r3 - r2) * (r2 - self.history[-3]) > 0:
            q = approach_order(self.midpoints[-3:], (r2 - self.history[-3]) / (r3 - r2))
        return r3 + (r3 - r2) * m3**q / (m2**q - m3**q)

    @property
    def log_limit(self):
        """Where the rates head if they approach p as p - b/|ln h| (a bound h^p |ln h| met sharply does: its
        local slope is p - 1/|ln h|): linear in 1/|ln h| through the last two rates, at 1/|ln h| = 0."""
        if len(self.history) < 2 or not self.log_approach or max(self.midpoints[-2:]) >= 1:
            return self.limit
        (u2, u3), (r2, r3) = (-1 / math.log(m) for m in self.midpoints[-2:]), self.history[-2:]
        return r3 + (r3 - r2) * u3 / (u2 - u3)

    @property
    def heads(self):
        """The limits the interval holds."""
        return (self.limit, self.log_limit) if self.log_approach else (self.limit,)

    @property
    def lo(self):
        return min(self.slope - max(2 * (self.se or 0.0), MIN_HALF), *self.heads, *self.rates)

    @property
    def hi(self):
        return max(self.slope + max(2 * (self.se or 0.0), MIN_HALF), *self.heads, *self.rates)

    @property
    def half(self):
        """Half the interval's width."""
        return (self.hi - self.lo) / 2

    @property
    def drifting(self):
        """Whether the moving rates, not the fit's residual, make the interval this wide."""
        return max(*self.heads, *self.rates) - min(*self.heads, *self.rates) >= 4 * (self.se or 0.0)

    def moving(self, towards, settled):
        """Whether the last two successive rates (the last one, if only one) each move towards `towards`
        by more than `settled`: the rates are not done changing in that direction."""
        steps = np.diff(self.history[-3:])
        return len(steps) > 0 and all((towards - self.history[-1]) * s > 0 and abs(s) > settled for s in steps)


def approach_order(m, ratio):
    """q with (m1^q - m2^q)/(m2^q - m3^q) = ratio (the ratio of two successive changes of r = p + c h^q at the
    rates' h m1 > m2 > m3), by bisection in [Q_MIN, Q_MAX]; the ends where the ratio lies beyond them."""
    def g(q):
        return (m[0] ** q - m[1] ** q) / (m[1] ** q - m[2] ** q)

    low, high = Q_MIN, Q_MAX
    if ratio <= g(low):
        return low
    if ratio >= g(high):
        return high
    for _ in range(200):
        middle = (low + high) / 2
        low, high = (middle, high) if g(middle) < ratio else (low, middle)
        if high - low < 1e-13:
            break
    return (low + high) / 2


def fit(h, errors, valid, k=FIT_LEVELS, log_factor=False, log_approach=False):
    """The least-squares slope of `fitted` with its standard error and the successive rates of the
    same levels (None if fewer than 2 usable levels); log_approach: see Fit."""
    every = [i for i in usable(errors, valid) if not log_factor or h[i] < 1]
    last = every[-k:]
    if len(last) < 2 or len({h[i] for i in last}) < 2:
        return None
    every = [i for i in every if i <= last[-1]]
    log_h = np.log([h[i] for i in every])
    log_e = np.log([errors[i] for i in every]) - (np.log(-log_h) if log_factor else 0.0)
    fitted_slope, _, se = regression(log_h[-len(last):], log_e[-len(last):])
    history = np.diff(log_e) / np.diff(log_h)
    midpoints = np.exp((log_h[1:] + log_h[:-1]) / 2)
    return Fit(fitted_slope, se, tuple(float(r) for r in history[-(len(last) - 1):]), tuple(last),
               tuple(float(r) for r in history), tuple(float(m) for m in midpoints), log_approach)


# --- the paper's proven rates ----------------------------------------------------------------------
# eps = theta h^p: the law's exponent p (config.Epsilon.p) decides which of the paper's hypotheses hold.
EPS_CONDITIONS = {
    "any eps": lambda p: True,
    "h/eps bounded (eps >~ h)": lambda p: p <= 1,
    "eps ~ h": lambda p: p == 1,
    # for p < 1, eps >= theta h holds with any theta once h is small; for p = 1 theta must be large
    # enough, a constant the paper does not give: the verdict cannot check it
    "eps >= theta h, theta large enough": lambda p: p <= 1,
    "eps >= theta sqrt(h)": lambda p: p <= 0.5,
    "h <~ eps": lambda p: p <= 1,
}
ALPHA_CONDITIONS = {
    "any alpha": lambda a: True,
    "alpha = 1": lambda a: a == 1,
    "alpha = 2": lambda a: a == 2,
    "alpha > 2": lambda a: a > 2,
}


@dataclass(frozen=True)
class Proven:
    """One estimate of the paper: for d in `dimensions`, alpha and eps as stated,
    norm = O(h^rate) (times |ln h| when log_factor); rate None: the paper says it is not covered."""
    dimensions: tuple
    alpha: str        # a key of ALPHA_CONDITIONS
    eps: str          # a key of EPS_CONDITIONS
    norm: str
    rate: str         # the exponent of h, an expression in alpha; None: not covered
    log_factor: bool
    reference: str
    conditions: str


# What the paper proves (its Lemma 3.1, Corollary 3.2, Lemmas 4.2, 4.4, 4.5), one record per (row, norm),
# plus the Γ_C and energy-type terms the same results bound. Norm names are the rate columns:
# H1 = |u - u_h|_H1, L2 = ||u - u_h||_L2, pos_gc = ||[u]_+ - [u_h]_+||_{L^{alpha+1}(Γ_C)},
# pos_gc_scaled = pos_gc^{(alpha+1)/2}, energy_err = (H1^2 + pos_gc^{alpha+1}/eps)^{1/2}.
PAPER_RATES = (
    Proven((2, 3), "any alpha", "h/eps bounded (eps >~ h)", "H1", "1", False, "Cor. 3.2 i",
           "u in W^{2,alpha+1}"),
    Proven((2, 3), "any alpha", "h/eps bounded (eps >~ h)", "energy_err", "1", False, "Lemma 3.1",
           "u in W^{2,alpha+1}; the left side of Lemma 3.1 is O(h^2 (1 + (h/eps)^{1/alpha}))"),
    Proven((2, 3), "any alpha", "eps ~ h", "pos_gc_scaled", "3/2", False, "Cor. 3.2 ii",
           "u in W^{2,alpha+1}"),
    Proven((2, 3), "any alpha", "eps ~ h", "pos_gc", "3/(alpha+1)", False, "Cor. 3.2 ii",
           "u in W^{2,alpha+1}; the (alpha+1)/2-th root of the scaled term"),
    Proven((2,), "alpha = 2", "eps >= theta h, theta large enough", "L2", "2", False, "Lemma 4.2",
           "u in W^{2,3}; Assumption 4.1 (H^2 stability of the companion problem)"),
    Proven((3,), "alpha = 2", "eps >= theta h, theta large enough", "L2", "8/5", False, "Lemma 4.4 (18)",
           "u in W^{2,3}; Assumption 4.1; quasi-uniform trace mesh on Γ_C"),
    Proven((3,), "alpha = 2", "eps >= theta sqrt(h)", "L2", "2", False, "Lemma 4.4 (19)",
           "u in W^{2,3}; Assumption 4.1; quasi-uniform trace mesh on Γ_C"),
    Proven((2,), "alpha > 2", "h <~ eps", "L2", "2", True, "Lemma 4.5",
           "u in W^{2,alpha+1}; h small enough; quasi-uniform trace mesh on Γ_C"),
    Proven((2, 3), "alpha = 1", "any eps", "L2", None, False, "Sect. 4",
           "the L2 analysis differentiates q_alpha(u) = [u]_+^alpha, which needs alpha > 1"),
)


# the proven rates of each contact method (problem.method): a method brings its own tuple of records
RECORDS = {"penalty": PAPER_RATES}


@dataclass(frozen=True)
class Expected:
    """The proven rate for one study and norm (None: not covered, `reason` says why)."""
    rate: float
    log_factor: bool = False
    reference: str = ""
    conditions: str = ""
    reason: str = ""


def base_norm(norm):
    """The exact-error norm a column estimates: L2_ref and diff_L2 are bounded as L2 is."""
    return norm.removeprefix("diff_").removesuffix("_ref")


def expected(dimension, alpha, p, norm, records=PAPER_RATES):
    """The best rate the `records` (a method's, RECORDS) prove for ‖·‖ = norm when d = dimension, alpha,
    eps = theta h^p."""
    if not alpha_admissible(dimension, alpha):
        bound = f"α = {alpha:g} > 3" if dimension == 3 and alpha > 3 else f"α = {alpha:g} < 1"
        return Expected(None, reason=f"{bound}, condition (5)")
    norm = base_norm(norm)
    records = [r for r in records if dimension in r.dimensions and r.norm == norm
               and ALPHA_CONDITIONS[r.alpha](alpha)]
    if not records:
        return Expected(None, reason=f"the paper proves no rate for {norm} with d = {dimension}, "
                                     f"alpha = {alpha:g}")
    holding = [r for r in records if EPS_CONDITIONS[r.eps](p)]
    if not holding:
        needs = " or ".join(sorted({r.eps for r in records}))
        return Expected(None, reason=f"eps = theta h^{p:g} is outside the paper's hypotheses ({needs})")
    silent = [r for r in holding if r.rate is None]
    if silent:
        return Expected(None, reference=silent[0].reference, reason=f"not covered: {silent[0].conditions}")
    best = max(holding, key=lambda r: (rate_value(r, alpha), not r.log_factor))
    return Expected(rate_value(best, alpha), best.log_factor, best.reference,
                    f"d = {dimension}, {best.alpha}, {best.eps}; {best.conditions}")


def rate_value(record, alpha):
    """A record's rate as a number for this alpha."""
    return float(expressions.parse(record.rate, ("alpha",))({"alpha": alpha}, expressions.numpy_functions()))


def alpha_admissible(dimension, alpha):
    """The paper's condition (5): alpha >= 1 in 2-D, 1 <= alpha <= 3 in 3-D."""
    return alpha >= 1 and (dimension == 2 or alpha <= 3)


# --- scalar quantities: observed order, Richardson extrapolation, GCI ------------------------------
GCI_SAFETY = 1.25  # Roache's factor of safety for three-grid studies (Celik et al. 2008)
ORDER_ITERATIONS = 100


@dataclass(frozen=True)
class GridConvergence:
    """Celik et al. (2008) on the three finest levels (1 = finest): apparent order p, the
    extrapolated value, and the fine-grid GCI, relative (gci) and as an absolute error band."""
    value: float
    order: float
    extrapolated: float
    gci: float
    band: float
    oscillatory: bool


def grid_convergence(h, phi):
    """Observed order, Richardson extrapolation and GCI_fine^21 from three levels (any order of
    h); None when the changes vanish (no order can be observed)."""
    (h1, phi1), (h2, phi2), (h3, phi3) = sorted(zip(h, phi))
    r21, r32 = h2 / h1, h3 / h2
    e21, e32 = phi2 - phi1, phi3 - phi2
    if e21 == 0 or e32 == 0 or r21 <= 1 or r32 <= 1:
        return None
    s = math.copysign(1.0, e32 / e21)
    p = _apparent_order(r21, r32, e32 / e21, s)
    if p is None or p <= 0:
        return None
    extrapolated = (r21**p * phi1 - phi2) / (r21**p - 1)
    band = GCI_SAFETY * abs(e21) / (r21**p - 1)
    gci = band / abs(phi1) if phi1 != 0 else math.inf
    return GridConvergence(phi1, p, extrapolated, gci, band, s < 0)


def _apparent_order(r21, r32, ratio, s):
    """Fixed point of p = |ln|e32/e21| + q(p)| / ln r21, q(p) = ln((r21^p - s)/(r32^p - s)) (Celik eq. 3)."""
    p = abs(math.log(abs(ratio))) / math.log(r21)
    for _ in range(ORDER_ITERATIONS):
        try:
            q = math.log((r21**p - s) / (r32**p - s))
        except (ValueError, ZeroDivisionError, OverflowError):
            return None
        p_next = abs(math.log(abs(ratio)) + q) / math.log(r21)
        if abs(p_next - p) < 1e-12 * max(1.0, p):
            return p_next
        p = p_next
    return p
