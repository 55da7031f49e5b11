"""Figures of a study (PNG and PDF): error vs h with slope triangles, work–precision, Newton iterations,
and the same curves for several studies. Page-sized with a fixed layout chosen from the number of norms
and the width (no tight_layout), log ticks as 10^k. matplotlib is imported here only (Agg)."""
import logging
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..analysis import rates
from ..analysis.rates import error_columns as norms
from ..config import names

# colour-blind safe (Okabe & Ito), and every curve also has its own marker and line style (print)
COLOURS = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000")
MARKERS = ("o", "s", "^", "D", "v", "P", "X")
LINESTYLES = ("-", "--", "-.", ":", (0, (5, 1)), (0, (3, 1, 1, 1)), (0, (1, 1)))
FONT_PT = 8  # every text of a figure, at its own size (≥ 8 pt once placed at 100 %)
PT_PER_INCH = 72.27  # TeX points: a figure `width` pt wide fills \includegraphics[width=width pt] exactly
# the fonts of a paper: Computer Modern (a default LaTeX article), STIX (Times-like journals), sans; a family
# list falls back glyph by glyph (cmr10 has no Greek: the labels write it as mathtext)
FONTS = {"cm": {"font.family": ["cmr10", "DejaVu Serif"], "mathtext.fontset": "cm", "axes.unicode_minus": False},
         "stix": {"font.family": ["STIXGeneral", "DejaVu Serif"], "mathtext.fontset": "stix"},
         "sans": {"font.family": ["DejaVu Sans"], "mathtext.fontset": "dejavusans"}}
STYLE = {
    "font.size": FONT_PT, "axes.formatter.use_mathtext": True,
    "axes.titlesize": FONT_PT, "legend.fontsize": FONT_PT, "xtick.labelsize": FONT_PT,
    "ytick.labelsize": FONT_PT, "axes.labelsize": FONT_PT, "legend.framealpha": 0.9,
    "axes.grid": True, "grid.alpha": 0.35, "grid.linewidth": 0.5, "lines.linewidth": 1.2,
    "lines.markersize": 4, "legend.handlelength": 2.6, "savefig.dpi": 200, "pdf.fonttype": 42,
}
FORMATS = ("png", "pdf")
SPACE = {"L2": "$L^2$", "H1": "$H^1$"}  # the model error's norms
WIDTH_PT = 345.0  # \textwidth of a default LaTeX article: placed at 100 %, the text stays 8 pt
WIDTH, HEIGHT = WIDTH_PT / PT_PER_INCH, 2.6  # inches, for callers that draw their own figure (limit_docs)
SHARED_PANEL = 2  # norms drawn in one panel; more norms get more panels
MIN_PANEL_PT = 160.0  # panels per row: as many as fit this wide
MAX_ASPECT = 1.2  # a figure at most this many times as tall as wide: a journal column's figure fits its page
# fixed margins around each panel, pt: tick labels and the axis label left and below, the legend under it
LEFT, RIGHT, TOP, BELOW, TITLE, LEGEND_LINE = 40.0, 8.0, 6.0, 26.0, 14.0, 11.5


@dataclass(frozen=True)
class Layout:
    """Figure options: width in pt; per_norm: one convergence figure per norm besides the default."""
    width: float = WIDTH_PT
    per_norm: bool = False


def write_all(rows, folder, proven=None, title="", fit_levels=rates.FIT_LEVELS, width=None, per_norm=False, shown=None,
              suffix="", font="cm"):
    """convergence, work_precision and newton (and convergence_<norm> with per_norm), each as PNG and PDF
    in `folder`, `suffix` added to their names; the paths written. `shown`: the plotted norms (default:
    all); `font`: a key of FONTS."""
    layout = Layout(width or WIDTH_PT, per_norm)
    curves = error_curves(rows)
    shown = [n for n in (shown or curves) if n in curves]
    with styled(font):
        figures = {"convergence": convergence(rows, proven, title, fit_levels, layout.width, shown),
                   "work_precision": work_precision(rows, title, layout.width, shown),
                   "newton": newton({"": rows}, title, layout.width)}
        if per_norm:
            figures.update({f"convergence_{n}": convergence(rows, proven, title, fit_levels, layout.width, [n])
                            for n in curves})
        return [path for name, fig in figures.items() if fig is not None
                for path in save(fig, folder, name + suffix)]


def write_comparison(studies, folder, width=None, font="cm"):
    """Several studies ({label: rows}): convergence and work–precision as a grid of one panel per norm,
    and Newton iterations; the paths written."""
    width = width or WIDTH_PT
    with styled(font):
        figures = {"compare_convergence": compare_convergence(studies, width),
                   "compare_work_precision": compare_work_precision(studies, width),
                   "compare_newton": newton(studies, "", width)}
        return [path for name, fig in figures.items() if fig is not None for path in save(fig, folder, name)]


def styled(font="cm"):
    """The STYLE in `font` (FONTS) as a context: figures are made and saved inside it, the caller's rcParams
    untouched."""
    import matplotlib
    logging.getLogger("fontTools").setLevel(logging.ERROR)  # cmr10's 1970 header dates, harmless, once a PDF
    return matplotlib.rc_context({**STYLE, **FONTS[font]})


def math_label(column):
    """A column as a figure shows it: a known norm or quantity in mathtext, any other name as it is."""
    tex = names.name(column).tex
    return tex if tex.startswith("$") else names.name(column).text


MATH = {"α": r"$\alpha$", "ε": r"$\varepsilon$", "θ": r"$\theta$", "Γ_C": r"$\Gamma_C$", "≥": r"$\geq$",
        "²": r"$^2$", "¹": r"$^1$", "·": r"$\cdot$", "π": r"$\pi$", "|ln h|": r"$|\ln h|$"}


def legend_of(name):
    """A sub-study's name as the values it varies: alpha1.5-p2 -> α = 1.5, p = 2; signorini -> the VI."""
    varied = re.fullmatch(r"alpha([-+.\de]+)-p([-+.\de]+)", name)
    if varied:
        return rf"$\alpha = {varied[1]}$, $p = {varied[2]}$"
    return "Signorini VI" if name == "signorini" else name


def mathtext(text):
    """Plain Unicode of a title or label with its Greek and Γ_C as mathtext (Computer Modern has no Greek
    text glyphs)."""
    for plain, math in MATH.items():
        text = text.replace(plain, math)
    return text.replace("$$", "")


def save(fig, folder, name):
    """Write the figure as folder/name.png and .pdf (its fixed size: no tight bounding box)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = [folder / f"{name}.{fmt}" for fmt in FORMATS]
    for path in paths:
        fig.savefig(path, metadata={"Creator": "signorini"} if path.suffix == ".pdf" else None)
    return paths


# --- one study ----------------------------------------------------------------------------------

def convergence(rows, proven=None, title="", fit_levels=rates.FIT_LEVELS, width=WIDTH_PT, shown=None):
    """The norms `shown` (default all) against h, log-log, SHARED_PANEL per panel or more where the
    figure would be too tall (norm_groups). A proven rate gets a dashed, open triangle marked "proven";
    a norm without one a filled triangle of its fitted slope; the fitted slope is in the legend either
    way. Triangles go above the panel's top curve and below its bottom one (clear of the others)."""
    curves = error_curves(rows)
    shown = [n for n in (shown or curves) if n in curves]
    if not shown:
        return None
    proven = proven or {}
    groups = norm_groups(len(shown), width, title)
    groups = [shown[start:start + size] for start, size in zip(np.cumsum([0] + groups[:-1]), groups)]
    fig, axes = panels(len(groups), width, max(map(len, groups)), title)
    for ax, group in zip(axes, groups):
        by_finest = sorted(group, key=lambda norm: curves[norm][1][-1])
        for norm in group:
            h, e = curves[norm]
            slope = rates.slope(h, e, fit_levels)
            fit = f"fit {slope:.2f}" if slope is not None else "one level"
            marked = norm in (by_finest[0], by_finest[-1])
            if norm in proven and not marked:
                fit += f", proven {_rate_text(proven[norm])}"
            line, = ax.loglog(h, e, label=f"{math_label(norm)}  ({fit})", **curve_style(shown.index(norm)))
            rate = proven.get(norm, slope)
            if marked and rate is not None and len(h) >= 2:
                slope_triangle(ax, h, e, rate, above=norm == by_finest[-1] and len(group) > 1,
                               colour=line.get_color(), proven=norm in proven)
        ax.set_xlabel("$h$")
        ax.set_ylabel("error")
        _legend_below(ax)
    _finish(fig, axes)
    return fig


def norm_groups(count, width, title=""):
    """Panel sizes for `count` norms: SHARED_PANEL a panel, or more a panel where that figure would be
    taller than MAX_ASPECT × width; never an empty place in the grid (sizes differ by one at most)."""
    ncols = max(1, int(width // MIN_PANEL_PT))
    for per in range(SHARED_PANEL, max(count, SHARED_PANEL) + 1):
        n = -(-count // per)
        if n > ncols:
            n = min(count, -(-n // ncols) * ncols)  # full rows
        sizes = [count // n + (k < count % n) for k in range(n)]
        if figure_height(n, width, max(sizes), title) <= MAX_ASPECT * width:
            return sizes
    return [count]


def work_precision(rows, title="", width=WIDTH_PT, shown=None):
    """Error against the cumulative wall time without form compilation (t_forms, a one-off cost of
    level 0 that would dominate the axis); with no t_forms column the axis label says it is included."""
    curves = error_curves(rows)
    shown = [n for n in (shown or curves) if n in curves]
    if not shown or any(row.get("time_s") is None for row in rows):
        return None
    total, compile_known = work(rows)
    ncol = min(3, len(shown))
    fig, (ax,) = panels(1, width, -(-len(shown) // ncol), title)
    for i, norm in enumerate(shown):
        k = [j for j, row in enumerate(rows) if row["converged"] and row.get(norm)]
        ax.loglog(total[k], curves[norm][1], label=math_label(norm), **curve_style(i))
    ax.set_xlabel(_work_label(compile_known))
    ax.set_ylabel("error")
    _legend_below(ax, ncol=ncol)
    _finish(fig, [ax])
    return fig


def newton(studies, title="", width=WIDTH_PT):
    """Newton iterations per level against the number of unknowns ({label: rows}; one study: label
    ""), levels that did not converge marked with a red ×."""
    labelled = [label for label in studies if label]
    failed_any = any(not row["converged"] for rows in studies.values() for row in rows)
    fig, (ax,) = panels(1, width, len(labelled) + failed_any, title)
    failed_label = "not converged"
    for i, (label, rows) in enumerate(studies.items()):
        ax.semilogx([row["dofs"] for row in rows], [row["newton_its"] for row in rows],
                    label=label or None, **curve_style(i))
        failed = [row for row in rows if not row["converged"]]
        if failed:
            ax.plot([row["dofs"] for row in failed], [row["newton_its"] for row in failed], "x",
                    color="#CC0000", markersize=8, markeredgewidth=1.8, label=failed_label, zorder=3)
            failed_label = None  # one legend entry for all studies
    _integer_axis(ax)
    ax.set_xlabel("degrees of freedom")
    ax.set_ylabel("Newton iterations")
    if ax.get_legend_handles_labels()[1]:
        _legend_below(ax)
    _finish(fig, [ax])
    return fig


# --- several studies ----------------------------------------------------------------------------

def compare_convergence(studies, width=WIDTH_PT):
    """A grid of one panel per norm, every study's error against h in it (the fitted slopes: compare's table)."""
    return _compare(studies, lambda rows, norm: error_curves(rows).get(norm), "$h$", width)


def compare_work_precision(studies, width=WIDTH_PT):
    """A grid of one panel per norm, every study's error against its cumulative wall time."""
    def curve(rows, norm):
        total = work(rows)[0]
        k = [j for j, row in enumerate(rows) if row["converged"] and row.get(norm) is not None]
        return (total[k], np.array([rows[j][norm] for j in k])) if k else None
    compile_known = all(work(rows)[1] for rows in studies.values())
    return _compare(studies, curve, _work_label(compile_known), width)


def work(rows):
    """(cumulative wall time per level, whether form compilation was taken out): t_forms is a one-off
    cost of level 0 that would dominate the axis; failed levels cost time too."""
    compile_known = all(row.get("t_forms") is not None for row in rows)
    seconds = [(row["time_s"] or 0.0) - (row["t_forms"] if compile_known else 0.0) for row in rows]
    return np.cumsum(seconds), compile_known


def _work_label(compile_known):
    return "cumulative time [s], " + ("JIT excluded" if compile_known else "JIT included")


def _compare(studies, curve, xlabel, width):
    """One panel per norm, the studies' curves in each, one legend for the figure (in the grid's free
    place, else under it); the fitted slopes are in compare's table."""
    all_norms = list(dict.fromkeys(norm for rows in studies.values() for norm in norms(rows)))
    if not all_norms:
        return None
    ncols = max(1, min(len(all_norms), int(width // MIN_PANEL_PT)))
    free = -len(all_norms) % ncols
    fig, axes = panels(len(all_norms) + free, width, 0, "", shared_legend=0 if free else len(studies))
    for ax, norm in zip(axes, all_norms):
        for i, (label, rows) in enumerate(studies.items()):
            xy = curve(rows, norm)
            if xy is not None and len(xy[0]):
                ax.loglog(*xy, label=legend_of(label), **curve_style(i))
        ax.set_ylabel(math_label(norm))
        ax.set_xlabel(xlabel)
    entries = {label: handle for ax in axes for handle, label in zip(*ax.get_legend_handles_labels())}
    for ax in axes[len(all_norms):]:  # the free place holds the legend
        ax.set_axis_off()
        ax.legend(entries.values(), entries.keys(), loc="center", frameon=False)
    if not free:
        fig.legend(entries.values(), entries.keys(), loc="lower center", frameon=False,
                   ncol=min(len(entries), 3), borderaxespad=0.3)
    _finish(fig, axes[:len(all_norms)])
    return fig


# --- pieces -------------------------------------------------------------------------------------

def error_curves(rows):
    """{norm: (h, error)} over the converged levels that measured it; norms with no point left out."""
    curves = {}
    for norm in norms(rows):
        points = [(row["h"], row[norm]) for row in rows if row["converged"] and row.get(norm)]
        if points:
            curves[norm] = tuple(np.array(v, dtype=float) for v in zip(*points))
    return curves


def slope_triangle(ax, h, e, rate, above=False, colour="black", proven=False):
    """A triangle of slope `rate` beside the finest segment of the curve (h, e), legs labelled 1 and the
    rate. A proven rate: dashed and open, its label "proven"; a fitted slope: filled, solid."""
    h_a, h_b, e_a, e_b = h[-1], h[-2], e[-1], e[-2]
    x_c, y_c = math.sqrt(h_a * h_b), math.sqrt(e_a * e_b)
    # 60 % of the last segment in log h, at least a fifth of the curve's range (readable on long curves)
    half = max((h_b / h_a) ** 0.3, (h[0] / h_a) ** 0.1)
    x0, x1 = x_c / half, x_c * half
    gap = 2.2 if above else 1 / 2.2  # off the curve by a factor 2.2 in the error
    y0 = y_c * gap / half ** rate
    y1 = y0 * (x1 / x0) ** rate
    corner = (x0, y1) if above else (x1, y0)
    ax.update_datalim([(x0 / 1.5, y0 / 1.7), (x1 * 1.5, y1 * 1.7)])  # keep the leg labels inside the axes
    from matplotlib.colors import to_rgba
    ax.fill([x0, corner[0], x1], [y0, corner[1], y1], facecolor="none" if proven else to_rgba(colour, 0.15),
            edgecolor=colour, linewidth=0.9, linestyle=(0, (3, 2)) if proven else "-", zorder=1)
    x_mid, y_mid = math.sqrt(x0 * x1), math.sqrt(y0 * y1)
    text = dict(color=colour, fontsize=FONT_PT)
    label = f"{_rate_text(rate)} proven" if proven else _rate_text(rate)
    if above:
        ax.text(x_mid, y1 * 1.12, "1", ha="center", va="bottom", **text)
        ax.text(x0 / 1.06, y_mid, label, ha="right", va="center", **text)
    else:
        ax.text(x_mid, y0 / 1.12, "1", ha="center", va="top", **text)
        ax.text(x1 * 1.06, y_mid, label, ha="left", va="center", **text)


def _rate_text(rate):
    return f"{rate:g}" if abs(rate - round(rate, 2)) < 1e-12 else f"{rate:.2f}"


def curve_style(i):
    """Colour, marker and line style of the i-th curve: distinguishable in grey print too, and no two of the
    first 7 × 7 alike (past 7 curves the marker and the dash shift against the colour)."""
    n = len(COLOURS)
    return {"color": COLOURS[i % n], "marker": MARKERS[(i + i // n) % n],
            "linestyle": LINESTYLES[(i + 2 * (i // n)) % n]}


def panels(count, width, legend_lines, title, shared_legend=0):
    """A figure `width` pt wide with `count` axes placed at fixed points (as many per row as fit
    MIN_PANEL_PT), room under each for its axis label and a legend of `legend_lines` entries, and under
    them all for a figure legend of `shared_legend` entries (three a line)."""
    from matplotlib.figure import Figure
    ncols = max(1, min(count, int(width // MIN_PANEL_PT)))
    ax_w, ax_h, row_h = _panel_size(width, ncols, legend_lines)
    foot = LEGEND_LINE * -(-shared_legend // 3) + 6.0 if shared_legend else 0.0
    height = figure_height(count, width, legend_lines, title) + foot
    fig = Figure(figsize=(width / PT_PER_INCH, height / PT_PER_INCH))
    axes = []
    for k in range(count):
        r, c = divmod(k, ncols)
        bottom = height - (TITLE if title else 0.0) - r * row_h - TOP - ax_h
        axes.append(fig.add_axes([(c * width / ncols + LEFT) / width, bottom / height, ax_w / width, ax_h / height]))
    if title:
        fig.text(0.5, 1 - 3.0 / height, mathtext(title), ha="center", va="top", fontsize=FONT_PT)
    return fig, axes


def _panel_size(width, ncols, legend_lines):
    """(axes width, axes height, row height) in pt."""
    ax_w = width / ncols - LEFT - RIGHT
    ax_h = min(0.62 * ax_w, 200.0)
    return ax_w, ax_h, TOP + ax_h + BELOW + LEGEND_LINE * legend_lines + 4.0


def figure_height(count, width, legend_lines, title=""):
    """The height (pt) of `count` panels with legends of `legend_lines` entries (panels())."""
    ncols = max(1, min(count, int(width // MIN_PANEL_PT)))
    return -(-count // ncols) * _panel_size(width, ncols, legend_lines)[2] + (TITLE if title else 0.0)


def _legend_below(ax, ncol=1):
    """The legend under the axes and its x label, never on the data."""
    below = BELOW / (ax.get_position().height * ax.figure.get_figheight() * PT_PER_INCH)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -below), ncol=ncol, frameon=False,
              borderaxespad=0.0, handletextpad=0.5, columnspacing=1.2)


def _integer_axis(ax):
    from matplotlib.ticker import MaxNLocator
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_ylim(0, ax.get_ylim()[1] + 0.8)  # room above the highest point


def readable_log_axis(axis):
    """One tick format on a log axis: decades labelled 10^k where two or more lie in view; otherwise
    ticks at 1, 2, 5 (or 1, 3) × 10^k, labelled m×10^k; no minor ticks."""
    from matplotlib.ticker import FuncFormatter, LogFormatterMathtext, LogLocator, NullLocator
    low, high = sorted(axis.get_view_interval())
    if low <= 0:
        return
    decades = math.floor(math.log10(high) + 1e-9) - math.ceil(math.log10(low) - 1e-9) + 1
    if decades >= 2:
        axis.set_major_locator(LogLocator(base=10, numticks=7))
        axis.set_major_formatter(LogFormatterMathtext())
    else:
        span = math.log10(high / low)
        axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0) if span < 1.2 else (1.0, 3.0)))
        axis.set_major_formatter(FuncFormatter(_scientific))
    axis.set_minor_locator(NullLocator())  # unlabelled minor ticks cost half the drawing time


def _scientific(value, _):
    """$m\\times10^{k}$, or $10^{k}$ for m = 1: LogFormatterMathtext's style with a mantissa."""
    exponent = math.floor(math.log10(value) + 1e-9)
    mantissa = value / 10 ** exponent
    return f"$10^{{{exponent}}}$" if abs(mantissa - 1) < 1e-6 else f"${mantissa:.2g}\\times10^{{{exponent}}}$"


def _finish(fig, axes):
    """Limits that keep every text inside its axes (clear of the tick labels), then one tick format per
    log axis."""
    for ax in axes:
        ax.autoscale_view()
    _keep_inside(fig, [ax for ax in axes if ax.texts])
    for ax in axes:
        for axis, scale in ((ax.xaxis, ax.get_xscale()), (ax.yaxis, ax.get_yscale())):
            if scale == "log":
                readable_log_axis(axis)


def _keep_inside(fig, axes, pad=3.0, rounds=4):
    """Widen the log limits of `axes` until their texts (triangle labels) lie `pad` pt inside them."""
    if not axes:
        return
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    renderer = FigureCanvasAgg(fig).get_renderer()
    scale = fig.dpi / PT_PER_INCH
    for _ in range(rounds):
        moved = False
        for ax in axes:
            box = ax.get_window_extent(renderer)
            extents = [text.get_window_extent(renderer) for text in ax.texts]
            out = [max(0.0, max(box.x0 + pad * scale - e.x0 for e in extents)),
                   max(0.0, max(e.x1 - box.x1 + pad * scale for e in extents)),
                   max(0.0, max(box.y0 + pad * scale - e.y0 for e in extents)),
                   max(0.0, max(e.y1 - box.y1 + pad * scale for e in extents))]
            moved |= any(out)
            _widen(ax.get_xlim(), out[0], out[1], box.width, ax.set_xlim)
            _widen(ax.get_ylim(), out[2], out[3], box.height, ax.set_ylim)
        if not moved:
            return


def _widen(limits, low_px, high_px, size_px, set_limits):
    """Move log limits out by what low_px and high_px take of the axis (a little more: the texts move too)."""
    if not (low_px or high_px):
        return
    low, high = math.log10(limits[0]), math.log10(limits[1])
    per_px = (high - low) / max(size_px - low_px - high_px, 0.3 * size_px)
    set_limits(10 ** (low - 1.15 * low_px * per_px), 10 ** (high + 1.15 * high_px * per_px))


# --- the ε → 0 studies ---------------------------------------------------------------------------

def model_error(rows, path, width=WIDTH_PT, font="cm"):
    """The model-error figure of `rows` (one mesh of an ε-sweep) as `path` (its suffix picks the format)."""
    with styled(font):
        model_error_figure(rows, width).savefig(path)
    return path


def model_error_figure(rows, width=WIDTH_PT):
    """H1 and L2 model error |u_ε,h − u_S,h| against ε, one curve per α, log-log, with the slope 1/α over
    the smaller half of the sweep; a Figure on the Agg canvas (no pyplot)."""
    alphas = sorted({r["alpha"] for r in rows})
    title = f"Model error of the compliance model on the fixed mesh N = {rows[0]['N']}"
    fig, axes = panels(2, width, len(alphas), title)
    for ax, norm in zip(axes, ("H1", "L2")):
        for k, alpha in enumerate(alphas):
            curve = [r for r in rows if r["alpha"] == alpha and r[norm] is not None]
            eps, err = [r["epsilon"] for r in curve], [r[norm] for r in curve]
            style = curve_style(k)
            ax.loglog(eps, err, color=style["color"], marker=style["marker"], label=rf"$\alpha = {alpha:g}$")
            tail = eps[len(eps) // 2:]  # through the last point
            ax.loglog(tail, [err[-1] * (e / eps[-1]) ** (1 / alpha) for e in tail], ls=":", lw=2,
                      color=style["color"], label=f"slope 1/{alpha:g}")
        ax.set_xlabel(r"$\varepsilon$")
        ax.set_ylabel(f"{SPACE[norm]} model error")
        _legend_below(ax, ncol=2)
    _finish(fig, axes)
    return fig
