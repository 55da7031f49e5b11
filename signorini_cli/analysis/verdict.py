"""A study's verdict against the paper: per norm the fitted rate, the proven rate and whether they agree;
per scalar quantity the observed order, Richardson extrapolation and GCI; the user's `expect:` block."""
import math
from dataclasses import asdict, dataclass, fields

from ..config import expressions
from . import rates

AGREES, EXCEEDS, BELOW, INCONCLUSIVE, NOT_COVERED = "agrees", "exceeds", "below", "inconclusive", "not covered"
ROUND_OFF = 1e-12  # a proven rate on the interval's edge is inside it, whatever the last bit says
MIN_LEVELS = 3  # two levels give a slope but no residual: nothing says how settled it is
GCI_QUANTITIES = ("contact_force", "penetration", "energy")  # data-only scenes: what a user quotes
RANGES = {"contact_force": (0.0, math.inf), "penetration": (0.0, math.inf), "energy": (-math.inf, math.inf)}


@dataclass(frozen=True)
class NormVerdict:
    """One rate column: the rate (the plain slope of log e against log h over the last levels) with its
    interval [lo, hi], the proven rate, the verdict and its one-line reason; where the proven bound carries
    |ln h|, `log_corrected` is the slope of e/|ln h|, a second, labelled value (None otherwise)."""
    norm: str
    observed: float
    log_corrected: float
    proven: float
    log_factor: bool
    verdict: str
    reference: str
    conditions: str
    levels: tuple  # N of the fitted levels
    lo: float = None
    hi: float = None
    reason: str = ""


@dataclass(frozen=True)
class QuantityEstimate:
    """A scalar quantity of interest on the finest level with its GCI error band (estimate None:
    `reason` says why there is none)."""
    quantity: str
    levels: tuple
    estimate: rates.GridConvergence
    reason: str = ""


@dataclass(frozen=True)
class Expectation:
    norm: str
    rate: float
    tolerance: float
    observed: float
    met: bool


@dataclass(frozen=True)
class Summary:
    norms: tuple
    quantities: tuple
    expectations: tuple
    fit_levels: int
    tolerance: float
    notes: tuple = ()
    outside_theory: bool = False

    @property
    def met(self):
        """True unless an `expect:` rate was missed."""
        return all(e.met for e in self.expectations)


def summarize(cfg, levels):
    """The verdict of a (possibly partial) study; the same on every rank (built from reduced values)."""
    norms = tuple(norm_verdict(cfg, levels, norm) for norm in rate_columns(levels))
    quantities = tuple(q for q in (quantity_estimate(cfg, levels, name) for name in GCI_QUANTITIES
                                   if cfg.problem.exact is None) if q is not None)
    fitted = {v.norm: v.observed for v in norms}
    expectations = tuple(expectation(norm, rate, cfg.expect.tolerance, fitted.get(norm))
                         for norm, rate in (cfg.expect.rates if cfg.expect else ()))
    return Summary(norms, quantities, expectations, cfg.verification.fit_levels, cfg.verification.tolerance,
                   notes(cfg), cfg.outside_theory)


def notes(cfg):
    """What the errors of a data-only scene are measured against."""
    v = cfg.verification
    if cfg.problem.exact is not None or v.reference_refinements == 0:
        return ()
    k = v.reference_refinements
    eps = ("each level's own eps" if v.reference_epsilon == "per_level"
           else "one eps, the law's on the finest reference mesh")
    return (f"*_ref: each level's error against the same problem solved on its own mesh refined {k} time"
            f"{'s' if k > 1 else ''}, at {eps}; ref_err_* = ||u_ref(k-1) - u_ref(k)||, the reference's own "
            "error estimate" + ("; the verdict is checked at depth k - 1 too" if k > 1 else ""),)


def rate_columns(levels):
    """Every error with a rate, in table order: L2, H1, then the extra columns."""
    if not levels:
        return []
    names = [n for n in ("L2", "H1") if any(n in lv.errors for lv in levels)]
    return names + [k[len("rate_"):] for k in levels[0].extra if k.startswith("rate_")]


def errors_of(levels, norm):
    return [lv.errors.get(norm) for lv in levels]


def norm_verdict(cfg, levels, norm):
    """Fit the last k levels of `norm` and compare its interval with the paper's rate for this study."""
    h, ok = [lv.h for lv in levels], [lv.outcome.converged for lv in levels]
    e, k = errors_of(levels, norm), cfg.verification.fit_levels
    proven = expected(cfg, norm)
    found = rates.fit(h, e, ok, k, log_approach=proven.log_factor)
    log_corrected = rates.fitted(h, e, ok, k, log_factor=True) if proven.log_factor else None
    used = tuple(levels[i].n for i in found.levels) if found else ()
    verdict, reason = decide(found, proven.rate, cfg.verification.tolerance,
                             proven.reason or proven.conditions)
    if verdict in (AGREES, EXCEEDS, BELOW):
        verdict, reason = shallower(cfg, levels, norm, proven, found, verdict, reason)
    if proven.log_factor and found is not None:
        reason += log_note(found, log_corrected)
    if proven.rate is not None:
        reason += hypotheses(proven, cfg.epsilon.p)
    if verdict in (AGREES, EXCEEDS, BELOW):
        reason += caveat(cfg, levels, found)
    return NormVerdict(norm, found and found.slope, log_corrected, proven.rate, proven.log_factor,
                       verdict, proven.reference, proven.conditions or proven.reason, used,
                       found and found.lo, found and found.hi, reason)


def log_note(found, log_corrected):
    """How a bound h^p |ln h| was read: its own local slope is p - 1/|ln h|, so the interval also holds
    where the rates head if they approach p that way; the slope of e/|ln h| beside it."""
    m = found.midpoints[-1] if found.midpoints else 1.0
    here = f"; 1/|ln h| = {-1 / math.log(m):.2f} here" if m < 1 else ""
    return (f"; the bound carries |ln h|: the rate is the plain slope, whose interval also holds where the rates "
            f"head if they approach p as p - b/|ln h| ({found.log_limit:.2f}{here}); "
            f"log-corrected fit (slope of e/|ln h|) {_rate(log_corrected)}")


UNCHECKED = ("theta large enough", "h small enough", "Assumption 4.1")  # hypotheses a run cannot check


def hypotheses(proven, p):
    """The paper's hypotheses behind the proven rate that no run can check (a constant it does not give, a
    stability assumption), said in the reason; eps = theta h^p with p < 1 meets "theta large enough" once h
    is small, whatever theta."""
    found = [c for c in UNCHECKED if c in (proven.conditions or "") and not (c.startswith("theta") and p < 1)]
    return f"; holds if {', '.join(found)} (not checked by a run)" if found else ""


def expected(cfg, norm):
    """The proven rate a column is checked against; columns comparing different problems, and
    problems outside the paper's hypotheses, are not covered (the reason says which hypothesis fails)."""
    if cfg.problem.pde == "elasticity":  # Cantin & Hild 2020 prove rates for -Δu = f only
        return rates.Expected(None, reason="the paper's estimates are for the scalar problem")
    if cfg.problem.exact_solves == "signorini":  # docs/limit.md; a Signorini study's exact solution is one
        return rates.Expected(None, reason="errors against the Signorini solution u_S: the paper bounds "
                                           "u_eps - u_eps,h only (total-error heuristics: docs/limit.md)")
    if cfg.element.degree != 1:
        return rates.Expected(None, reason="the paper proves its rates for P1 elements; element.degree "
                                           f"{cfg.element.degree} is measured only (docs/elements.md)")
    if not cfg.verification.regular:  # the user says the paper's regularity hypothesis fails
        return rates.Expected(None, reason="the paper's rates assume u in W^{2,alpha+1}; this scene's solution "
                                           "is singular (verification.regular: false, Remark 3.4)")
    p = cfg.epsilon.p
    g = cfg.problem.g
    if g is not None and p != 0 and "eps" not in g.names and not _zero(g):
        return rates.Expected(None, reason=f"g = {g.text} does not scale with eps = {cfg.epsilon.formula()} "
                                           "-> 0: the flux g/eps on Γ_C grows without bound, so u_eps has no "
                                           "h-independent W^{2,alpha+1} bound (Cor. 3.2 assumes one)")
    if norm.startswith("diff_") and p != 0:
        return rates.Expected(None, reason="successive levels have different eps, so their difference "
                                           "contains u_eps(h) - u_eps(h/2): no discretisation rate applies")
    if norm.endswith("_ref") and cfg.verification.reference_epsilon == "fixed" and p != 0:
        return rates.Expected(None, reason="reference_epsilon: fixed compares each level with a problem at "
                                           "another eps: the error contains the model error")
    if cfg.problem.method not in rates.RECORDS:
        return rates.Expected(None, reason=f"no proven rates recorded for problem.method {cfg.problem.method}")
    return rates.expected(cfg.dimension, cfg.alpha, p, norm, rates.RECORDS[cfg.problem.method])


def _zero(expression):
    """g = 0 written as a constant (no variables): the Signorini data, no flux."""
    return not (expression.names - set(expressions.CONSTANTS)) and expression({}, expressions.math_functions()) == 0


# a successive rate moving by less than this per level is settled at the two decimals a verdict shows
SETTLED = 1e-3


def decide(found, proven, widest, why=""):
    """(verdict, reason) of a fit (rates.Fit or None) against a proven rate (None: not covered, `why`
    says which hypothesis fails). Every definite class needs the same evidence: MIN_LEVELS fitted levels and
    an interval no wider than ± widest; `below` and `exceeds` also rates not still moving towards the
    proven rate from within the tolerance of it. Otherwise inconclusive, the reason saying which is missing."""
    if proven is None:
        return NOT_COVERED, why or "the paper proves no rate here"
    if found is None or len(found.levels) < MIN_LEVELS:
        fitted = 0 if found is None else len(found.levels)
        return INCONCLUSIVE, f"too few levels: {fitted} converged in the fit, {MIN_LEVELS} needed"
    shown = f"rate {found.slope:.2f} in [{found.lo:.2f}, {found.hi:.2f}]"
    inside = found.lo - ROUND_OFF <= proven <= found.hi + ROUND_OFF
    where = "contains" if inside else ("is above" if found.lo > proven else "is below")
    if found.half > widest:
        cause = (f"rates still drifting ({_moves(found)})" if found.drifting else "the fit's residual")
        return INCONCLUSIVE, f"{shown} {where} proven {proven:.3g} but is wider than ± {widest:g}: {cause}"
    if inside:
        return AGREES, f"{shown} contains proven {proven:.3g}"
    gap = found.lo - proven if found.lo > proven else proven - found.hi
    if gap <= widest and found.moving(proven, SETTLED):
        return INCONCLUSIVE, (f"{shown} {where} proven {proven:.3g}, but the rates still move towards it "
                              f"({_moves(found)}): more levels decide")
    if found.lo > proven:
        return EXCEEDS, f"{shown} > proven {proven:.3g}: the bound is not sharp on this case"
    return BELOW, f"{shown} < proven {proven:.3g}: below the bound (a finding, or a hypothesis fails)"


def _moves(found):
    """The last successive rates, 'a -> b -> c'."""
    return " -> ".join(f"{r:.3f}" for r in found.history[-3:])


def shallower(cfg, levels, norm, proven, deep, verdict, reason):
    """A reference-error verdict checked one reference depth shallower (errors `<norm>_shallow`, measured
    when reference_refinements >= 2): the class must not depend on the depth, else it is inconclusive."""
    shallow = [lv.errors.get(f"{norm}_shallow") for lv in levels]
    if not norm.endswith("_ref") or not any(shallow):
        return verdict, reason
    found = rates.fit([lv.h for lv in levels], shallow, [lv.outcome.converged for lv in levels],
                      cfg.verification.fit_levels, log_approach=proven.log_factor)
    other, _ = decide(found, proven.rate, cfg.verification.tolerance)
    if other == verdict:
        return verdict, reason
    k = cfg.verification.reference_refinements
    return INCONCLUSIVE, (f"references {k} refinements finer: {deep.slope:.2f} ({verdict}), {k - 1} finer: "
                          f"{_rate(found and found.slope)} ({other}): the reference depth decides")


def caveat(cfg, levels, found):
    """A constant eps satisfies 'eps >~ h' only once h <~ eps: say so, and whether the fitted levels are there."""
    if cfg.epsilon.p != 0:
        return ""
    finest = levels[found.levels[-1]]
    where = "reached" if finest.h <= finest.eps else "not reached"
    return f"; eps constant: the bound holds only once h <~ eps ({where} here: h/eps = {finest.h / finest.eps:.2g})"


def quantity_estimate(cfg, levels, name):
    """GCI of a quantity from the three finest converged levels where it was measured: only when every
    level solves one continuous problem (constant eps, fixed data), and never an extrapolated value
    outside the quantity's range."""
    if not any(name in lv.extra for lv in levels):
        return None
    found = [(lv.h, lv.extra[name], lv.n) for lv in levels
             if lv.outcome.converged and lv.extra.get(name) is not None]
    last = found[-3:]
    ns = tuple(x[2] for x in last)
    if cfg.epsilon.p != 0:
        return QuantityEstimate(name, ns, None, f"eps = {cfg.epsilon.formula()} changes with h: each level "
                                                "solves another continuous problem, no limit to extrapolate to")
    if len(last) < 3:
        return QuantityEstimate(name, ns, None, "needs three converged levels")
    estimate = rates.grid_convergence([x[0] for x in last], [x[1] for x in last])
    if estimate is None:
        return QuantityEstimate(name, ns, None, "no order observable")
    low, high = RANGES[name]
    if not low <= estimate.extrapolated <= high:
        return QuantityEstimate(name, ns, None, f"extrapolated {estimate.extrapolated:.3e} outside "
                                                f"[{low:g}, {high:g}]: the levels are not in the asymptotic range")
    return QuantityEstimate(name, ns, estimate)


def expectation(norm, rate, tolerance, observed):
    met = observed is not None and observed >= rate - tolerance - ROUND_OFF
    return Expectation(norm, rate, tolerance, observed, met)


SUMMARY_COLUMNS = ("kind", "name", "observed_rate", "rate_lo", "rate_hi", "log_corrected_rate", "proven_rate",
                   "log_factor", "verdict", "reason", "paper", "conditions", "levels", "value", "order",
                   "extrapolated", "gci", "band", "oscillatory", "expected_rate", "tolerance", "met")


def summary_rows(summary):
    """One row per norm, quantity and expectation, over the union of their fields."""
    rows = []
    for v in summary.norms:
        rows.append(dict(kind="norm", name=v.norm, observed_rate=v.observed, rate_lo=v.lo, rate_hi=v.hi,
                         log_corrected_rate=v.log_corrected, proven_rate=v.proven, log_factor=v.log_factor,
                         verdict=v.verdict, reason=v.reason,
                         paper=v.reference, conditions=v.conditions, levels=_levels(v.levels)))
    for q in summary.quantities:
        row = dict(kind="quantity", name=q.quantity, levels=_levels(q.levels), reason=q.reason or None)
        if q.estimate is not None:
            row.update(asdict(q.estimate))
        rows.append(row)
    for e in summary.expectations:
        rows.append(dict(kind="expect", name=e.norm, observed_rate=e.observed, expected_rate=e.rate,
                         tolerance=e.tolerance, met=e.met))
    return rows


def from_rows(cfg, rows):
    """The Summary that summary_rows wrote for `cfg` (summary.csv read back): a report shows the run's verdict
    as it was decided, not decided again."""
    norms, quantities, expectations = [], [], []
    for r in rows:
        ns = tuple(int(n) for n in str(r.get("levels") or "").split())
        if r["kind"] == "norm":
            norms.append(NormVerdict(r["name"], r["observed_rate"], r.get("log_corrected_rate"), r["proven_rate"],
                                     bool(r["log_factor"]), r["verdict"], r["paper"] or "", r["conditions"] or "",
                                     ns, r["rate_lo"], r["rate_hi"], r["reason"] or ""))
        elif r["kind"] == "quantity":
            grid = {f.name: r[f.name] for f in fields(rates.GridConvergence)}
            estimate = rates.GridConvergence(**grid) if r["value"] is not None else None
            quantities.append(QuantityEstimate(r["name"], ns, estimate, r["reason"] or ""))
        else:
            expectations.append(Expectation(r["name"], r["expected_rate"], r["tolerance"], r["observed_rate"],
                                            r["met"]))
    return Summary(tuple(norms), tuple(quantities), tuple(expectations), cfg.verification.fit_levels,
                   cfg.verification.tolerance, notes(cfg), cfg.outside_theory)


def _levels(ns):
    return " ".join(str(n) for n in ns)


def _rate(value):
    return "-" if value is None else f"{value:.2f}"
