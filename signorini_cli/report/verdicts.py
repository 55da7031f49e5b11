"""A study's verdict as the terminal, Markdown and LaTeX show it (the verdict itself: analysis.verdict)."""
import textwrap

from ..config import names
from . import latex

TERMINAL_WIDTH = 120  # the verdict block wraps its last column to fit a terminal of this width


def format_summary(summary):
    """The verdict block printed under the rate table."""
    lines = []
    if summary.outside_theory:
        lines.append("OUTSIDE THE PAPER'S THEORY (outside_theory: true): no verdict compares with a proven rate")
    if summary.norms:  # a study without error norms (a Hertz scene: its quantities) has no rate verdict
        lines += textwrap.wrap(f"verification: rate = slope of log e against log h over the last "
                               f"{summary.fit_levels} levels; interval: the fit ± 2 standard errors, the successive "
                               f"rates and where they head; every class needs an interval within ± "
                               f"{summary.tolerance:g}", TERMINAL_WIDTH)
        lines += [f"  {note}" for note in summary.notes]
        rows = [("norm", "observed", "interval", "proven", "verdict", "why")]
        for v in summary.norms:
            observed = _rate(v.observed) + (f" (log-corrected {_rate(v.log_corrected)})" if v.log_factor else "")
            proven = "-" if v.proven is None else f"{v.proven:g}" + (" |ln h|" if v.log_factor else "")
            why = f"{v.reference}: {v.reason}" if v.reference and v.proven is not None else v.reason
            rows.append((v.norm, observed, interval(v), proven, v.verdict, why))
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


def interval(v):
    """[lo, hi] of a verdict's fitted rate, '-' without one."""
    return "-" if v.lo is None else f"[{v.lo:.2f}, {v.hi:.2f}]"


def markdown_lines(summary):
    """The verdicts under a markdown rate table: one line per norm, class and interval (none without norms)."""
    if not summary.norms:
        return []
    lines = ["", "| norm | observed | interval | proven | verdict | why |", "|---|---|---|---|---|---|"]
    for v in summary.norms:
        proven = "–" if v.proven is None else f"{v.proven:g}"
        observed = _rate(v.observed) + (f" (log-corrected {_rate(v.log_corrected)})" if v.log_factor else "")
        lines.append(f"| {v.norm} | {observed} | {interval(v)} | {proven} | {v.verdict} | "
                     f"{v.reason.replace('|', chr(92) + '|')} |")  # |ln h| stays |ln h| in a table cell
    return lines


def latex_table(summary, key):
    """verdict.tex: one booktabs float, per norm the observed rate with its interval, the proven rate, the
    class and the paper's result that proves it."""
    rows = [[names.name(v.norm).tex, "--" if v.observed is None else latex.rate(v.observed),
             "--" if v.lo is None else f"$[{v.lo:.2f}, {v.hi:.2f}]$",
             "--" if v.proven is None else f"${latex.constant(v.proven)}$", latex.escape(v.verdict),
             latex.escape(v.reference) or "--"] for v in summary.norms]
    cells = [(head, [row[k] for row in rows]) for k, head in enumerate(
        ["norm", "observed", "interval", "proven", "verdict", "result"])]
    caption = (f"Observed rates fitted over the last {summary.fit_levels} levels (slope of $\\log e$ against "
               "$\\log h$) with their intervals, against the rates the paper proves.")
    return "% verdict written by signorini; needs \\usepackage{booktabs}\n" + latex.table(
        cells, [], caption, key, len(rows), align="lrrrll")


def _quantity_row(q):
    g = q.estimate
    if g is None:
        return (q.quantity, "-", "-", "-", "-", q.reason)
    finest = f"{g.value:.6e}"
    order = f"{g.order:.2f}" + (" (oscillatory)" if g.oscillatory else "")
    return (q.quantity, finest, order, f"{g.extrapolated:.6e}", f"{100 * g.gci:.3g}%", f"± {g.band:.2e}")


def _aligned(rows, width=TERMINAL_WIDTH):
    """Rows in aligned columns; a last column that would pass `width` wraps under itself."""
    widths = [max(len(str(row[i])) for row in rows) for i in range(len(rows[0]) - 1)]
    lead = 2 + sum(w + 2 for w in widths)
    room = max(width - lead, 30)
    lines = []
    for row in rows:
        head = "  " + "".join(str(cell).ljust(w + 2) for cell, w in zip(row, widths))
        last = textwrap.wrap(str(row[-1]), room) or [""]
        lines += [(head if k == 0 else " " * lead) + part for k, part in enumerate(last)]
    return [line.rstrip() for line in lines]


def _rate(value):
    return "-" if value is None else f"{value:.2f}"

