"""A study's verdict against the paper: per norm the fitted rate, the proven rate and whether they agree;
per scalar quantity the observed order, Richardson extrapolation and GCI; the user's `expect:` block."""
from dataclasses import asdict, dataclass

from ..config import MESH_KINDS
from . import rates

AGREES, BELOW, NOT_COVERED, NO_RATE = "agrees", "below theory", "not covered", "no rate"
ROUND_OFF = 1e-12  # an observed rate equal to proven - tolerance agrees, whatever the last bit says
GCI_QUANTITIES = ("contact_force", "penetration", "energy")  # data-only scenes: what a user quotes


@dataclass(frozen=True)
class NormVerdict:
    """One rate column: fitted rate over the last levels (of e/|ln h| when the proven rate carries
    |ln h|; `plain` is the fit of e itself), the proven rate and the verdict."""
    norm: str
    observed: float
    plain: float
    proven: float
    log_factor: bool
    verdict: str
    reference: str
    conditions: str
    levels: tuple  # N of the fitted levels
    lo: float = None  # the observed rate's interval
    hi: float = None
    reason: str = ""


@dataclass(frozen=True)
class QuantityEstimate:
    """A scalar quantity of interest on the finest level with its GCI error band."""
    quantity: str
    levels: tuple
    estimate: rates.GridConvergence  # None: no order observable (e.g. a constant quantity)


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

    @property
    def met(self):
        """True unless an `expect:` rate was missed."""
        return all(e.met for e in self.expectations)


def summarize(cfg, levels):
    """The verdict of a (possibly partial) study; the same on every rank (built from reduced values)."""
    norms = tuple(norm_verdict(cfg, levels, norm) for norm in rate_columns(levels))
    quantities = tuple(q for q in (quantity_estimate(levels, name) for name in GCI_QUANTITIES
                                   if cfg.problem.exact is None) if q is not None)
    fitted = {v.norm: v.observed for v in norms}
    expectations = tuple(expectation(norm, rate, cfg.expect.tolerance, fitted.get(norm))
                         for norm, rate in (cfg.expect.rates if cfg.expect else ()))
    return Summary(norms, quantities, expectations, cfg.verification.fit_levels, cfg.verification.tolerance,
                   notes(cfg))


def notes(cfg):
    """What the errors of a data-only scene are measured against."""
    v = cfg.verification
    if cfg.problem.exact is not None or v.reference_refinements == 0:
        return ()
    if cfg.mesh.kind in MESH_KINDS:
        where = f"at N={cfg.mesh.refinements[-1] * 2 ** v.reference_refinements}"
    else:  # gmsh/file meshes: N counts cells, known once the finest level is built
        where = f"on {2 ** (cfg.dimension * v.reference_refinements)} times the finest level's cells"
    eps = ("each level's own eps" if v.reference_epsilon == "per_level"
           else "one eps, the law's on the reference mesh")
    return (f"*_ref: errors against a reference solution {where} ({v.reference_refinements} uniform "
            f"refinement{'s' if v.reference_refinements > 1 else ''} of the finest level), solved at {eps}",)


def rate_columns(levels):
    """Every error with a rate, in table order: L2, H1, then the extra columns."""
    if not levels:
        return []
    names = [n for n in ("L2", "H1") if any(n in lv.errors for lv in levels)]
    return names + [k[len("rate_"):] for k in levels[0].extra if k.startswith("rate_")]


def errors_of(levels, norm):
    return [lv.errors.get(norm) for lv in levels]


def norm_verdict(cfg, levels, norm):
    """Fit the last k levels of `norm` and compare with the paper's rate for this study."""
    h, ok = [lv.h for lv in levels], [lv.outcome.converged for lv in levels]
    e, k = errors_of(levels, norm), cfg.verification.fit_levels
    proven = expected(cfg, norm)
    plain = rates.fitted(h, e, ok, k)
    observed = rates.fitted(h, e, ok, k, log_factor=True) if proven.log_factor else plain
    used = tuple(levels[i].n for i in rates.usable(e, ok)[-k:])
    return NormVerdict(norm, observed, plain, proven.rate, proven.log_factor,
                       decide(observed, proven.rate, cfg.verification.tolerance),
                       proven.reference, proven.conditions or proven.reason, used, observed, observed, "")


def expected(cfg, norm):
    """The proven rate a column is checked against; columns comparing different problems are not covered."""
    if cfg.study_type == "signorini" or cfg.problem.exact_solves == "signorini":  # docs/limit.md
        return rates.Expected(None, reason="errors against the Signorini solution u_S: the paper bounds "
                                           "u_eps - u_eps,h only (total-error heuristics: docs/limit.md)")
    if not cfg.verification.regular:  # the user says the paper's regularity hypothesis fails
        return rates.Expected(None, reason="the paper's rates assume u in W^{2,alpha+1}; this scene's solution "
                                           "is singular (verification.regular: false, Remark 3.4)")
    p = cfg.epsilon.p
    if norm.startswith("diff_") and p != 0:
        return rates.Expected(None, reason="successive levels have different eps, so their difference "
                                           "contains u_eps(h) - u_eps(h/2): no discretisation rate applies")
    if norm.endswith("_ref") and cfg.verification.reference_epsilon == "fixed" and p != 0:
        return rates.Expected(None, reason="reference_epsilon: fixed compares each level with a problem at "
                                           "another eps: the error contains the model error")
    return rates.expected(cfg.dimension, cfg.alpha, p, norm)


def decide(observed, proven, tolerance):
    """agrees (observed >= proven - tolerance), below theory, not covered (no proven rate), no rate."""
    if proven is None:
        return NOT_COVERED
    if observed is None:
        return NO_RATE
    return AGREES if observed >= proven - tolerance - ROUND_OFF else BELOW


def quantity_estimate(levels, name):
    """GCI of a quantity from the three finest converged levels where it was measured."""
    found = [(lv.h, lv.extra[name], lv.n) for lv in levels
             if lv.outcome.converged and lv.extra.get(name) is not None]
    if not any(name in lv.extra for lv in levels):
        return None
    last = found[-3:]
    estimate = rates.grid_convergence([x[0] for x in last], [x[1] for x in last]) if len(last) == 3 else None
    return QuantityEstimate(name, tuple(x[2] for x in last), estimate)


def expectation(norm, rate, tolerance, observed):
    met = observed is not None and observed >= rate - tolerance - ROUND_OFF
    return Expectation(norm, rate, tolerance, observed, met)


# --- output ------------------------------------------------------------------------------------------

def format_summary(summary):
    """The verdict block printed under the rate table."""
    lines = [f"verification: rates fitted over the last {summary.fit_levels} levels, "
             f"agrees when observed >= proven - {summary.tolerance:g}"]
    lines += [f"  {note}" for note in summary.notes]
    rows = [("norm", "observed", "proven", "verdict", "paper")]
    for v in summary.norms:
        observed = _rate(v.observed) + (f" (plain {_rate(v.plain)}, fit of e/|ln h|)" if v.log_factor else "")
        proven = "-" if v.proven is None else f"{v.proven:g}" + (" |ln h|" if v.log_factor else "")
        why = v.reference or v.conditions
        if v.reference and v.proven is None:
            why = f"{v.reference}: {v.conditions}"
        rows.append((v.norm, observed, proven, v.verdict, why))
    lines += _aligned(rows)
    if summary.quantities:
        lines.append("quantities of interest (three finest levels; Celik et al. 2008, safety factor 1.25):")
        rows = [("quantity", "finest", "order", "extrapolated", "GCI_fine", "error band")]
        rows += [_quantity_row(q) for q in summary.quantities]
        lines += _aligned(rows)
    for e in summary.expectations:
        status = "met" if e.met else "NOT MET"
        lines.append(f"expect {e.norm} >= {e.rate:g} - {e.tolerance:g}: {status} (observed {_rate(e.observed)})")
    return "\n".join(lines)


def _quantity_row(q):
    g = q.estimate
    if g is None:
        why = "no order observable" if len(q.levels) == 3 else "needs three converged levels"
        return (q.quantity, "-", "-", "-", "-", why)
    finest = f"{g.value:.6e}"
    order = f"{g.order:.2f}" + (" (oscillatory)" if g.oscillatory else "")
    return (q.quantity, finest, order, f"{g.extrapolated:.6e}", f"{100 * g.gci:.3g}%", f"± {g.band:.2e}")


def _aligned(rows):
    widths = [max(len(str(row[i])) for row in rows) for i in range(len(rows[0]))]
    return ["  " + "  ".join(str(cell).ljust(w) for cell, w in zip(row, widths)).rstrip() for row in rows]


def _rate(value):
    return "-" if value is None else f"{value:.2f}"


SUMMARY_COLUMNS = ("kind", "name", "observed_rate", "plain_rate", "proven_rate", "log_factor", "verdict",
                   "paper", "conditions", "levels", "value", "order", "extrapolated", "gci", "band",
                   "oscillatory", "expected_rate", "tolerance", "met")


def summary_rows(summary):
    """One row per norm, quantity and expectation, over the union of their fields."""
    rows = []
    for v in summary.norms:
        rows.append(dict(kind="norm", name=v.norm, observed_rate=v.observed, plain_rate=v.plain,
                         proven_rate=v.proven, log_factor=v.log_factor, verdict=v.verdict,
                         paper=v.reference, conditions=v.conditions, levels=_levels(v.levels)))
    for q in summary.quantities:
        row = dict(kind="quantity", name=q.quantity, levels=_levels(q.levels))
        if q.estimate is not None:
            row.update(asdict(q.estimate))
        rows.append(row)
    for e in summary.expectations:
        rows.append(dict(kind="expect", name=e.norm, observed_rate=e.observed, expected_rate=e.rate,
                         tolerance=e.tolerance, met=e.met))
    return rows


def write_h5(group, summary):
    """The summary as HDF5 attributes: one subgroup per norm, quantity and expectation."""
    group.attrs["fit_levels"] = summary.fit_levels
    group.attrs["tolerance"] = summary.tolerance
    group.attrs["expectations_met"] = summary.met
    if summary.notes:
        group.attrs["notes"] = "\n".join(summary.notes)
    for row in summary_rows(summary):
        sub = group.require_group(row["kind"]).create_group(row["name"])
        for key, value in row.items():
            if key not in ("kind", "name") and value is not None:
                sub.attrs[key] = value


def _levels(ns):
    return " ".join(str(n) for n in ns)
