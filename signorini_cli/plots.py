"""Figures of a study (PNG and PDF): error vs h with slope triangles, work–precision, Newton iterations,
and the same curves overlaid for several studies. matplotlib is imported here only, headless (Agg)."""
import math
from pathlib import Path

import numpy as np

from .report import FIT_LEVELS, LABELS, fitted_slope, norms

# colour-blind safe (Okabe & Ito), and every curve also has its own marker and line style (print)
COLOURS = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000")
MARKERS = ("o", "s", "^", "D", "v", "P", "X")
LINESTYLES = ("-", "--", "-.", ":", (0, (5, 1)), (0, (3, 1, 1, 1)), (0, (1, 1)))
STYLE = {
    "font.family": "serif", "font.serif": ["STIXGeneral", "DejaVu Serif"], "mathtext.fontset": "stix",
    "font.size": 10, "axes.titlesize": 9.5, "legend.fontsize": 9, "legend.framealpha": 0.9,
    "xtick.labelsize": 9, "ytick.labelsize": 9, "axes.grid": True, "grid.alpha": 0.35,
    "grid.linewidth": 0.5, "lines.linewidth": 1.4, "lines.markersize": 5.5,
    "savefig.dpi": 200, "savefig.bbox": "tight", "pdf.fonttype": 42,  # TrueType: text stays text
}
FORMATS = ("png", "pdf")
WIDTH, HEIGHT = 5.0, 3.8  # inches: one figure per column of a two-column page at 200 dpi
SHARED_PANEL = 2  # norms drawn in one panel; with more, one panel per norm
GRID_COLUMNS = 3


def write_all(rows, folder, proven=None, title=""):
    """convergence, work_precision and newton, each as PNG and PDF in `folder`; the paths written."""
    with styled():
        figures = {"convergence": convergence(rows, proven, title),
                   "work_precision": work_precision(rows, title),
                   "newton": newton({"": rows}, title)}
        return [path for name, fig in figures.items() if fig is not None for path in save(fig, folder, name)]


def write_comparison(studies, folder):
    """Overlays of several studies ({label: rows}): convergence, work–precision, Newton; paths written."""
    with styled():
        figures = {"compare_convergence": compare_convergence(studies),
                   "compare_work_precision": compare_work_precision(studies),
                   "compare_newton": newton(studies, "")}
        return [path for name, fig in figures.items() if fig is not None for path in save(fig, folder, name)]


def styled():
    """The STYLE as a context: figures are made and saved inside it, the caller's rcParams untouched."""
    import matplotlib
    return matplotlib.rc_context(STYLE)


def save(fig, folder, name):
    """Write the figure as folder/name.png and .pdf."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = [folder / f"{name}.{fmt}" for fmt in FORMATS]
    for path in paths:
        fig.savefig(path, metadata={"Creator": "signorini"} if path.suffix == ".pdf" else None)
    return paths


# --- one study ----------------------------------------------------------------------------------

def convergence(rows, proven=None, title=""):
    """Every measured norm against h, log-log, with a slope triangle per norm labelled with the proven
    rate when one is given, else with the slope fitted over the last levels. Up to SHARED_PANEL norms
    share one panel; more get a panel each (their curves and triangles would overlap)."""
    curves = error_curves(rows)
    if not curves:
        return None
    proven = proven or {}
    groups = [list(curves)] if len(curves) <= SHARED_PANEL else [[norm] for norm in curves]
    fig, axes = _grid(len(groups))
    for ax, group in zip(axes, groups):
        top = max(group, key=lambda norm: curves[norm][1][-1])
        for norm in group:
            h, e = curves[norm]
            slope = fitted_slope(h, e)
            fit = f"fitted slope {slope:.2f}" if slope is not None else "one level"
            label = f"{math_label(norm)}  ({fit})" if len(group) > 1 else fit
            line, = ax.loglog(h, e, label=label, **curve_style(list(curves).index(norm)))
            rate = proven.get(norm, slope)
            if rate is not None and len(h) >= 2:
                slope_triangle(ax, h, e, rate, above=norm == top and len(group) > 1, colour=line.get_color())
        ax.set_xlabel(r"mesh size $h$ (largest cell diameter)")
        ax.set_ylabel("error" if len(group) > 1 else math_label(group[0]))
        ax.legend(title=_triangle_kind([norm in proven for norm in group]), title_fontsize=8, loc="best")
    _finish(fig, axes[0], title)
    return fig


def work_precision(rows, title=""):
    """Error against wall time: cumulative over the study (left) and the level's own (right)."""
    curves = error_curves(rows)
    if not curves or any(row.get("time_s") is None for row in rows):
        return None
    fig, (left, right) = _figure(ncols=2, sharey=True, width=2 * WIDTH * 0.8)
    total = np.cumsum([row["time_s"] for row in rows])  # failed levels cost time too
    ok = [k for k, row in enumerate(rows) if row["converged"]]
    for i, (norm, (_, e)) in enumerate(curves.items()):
        k = [j for j in ok if rows[j].get(norm) is not None]
        left.loglog(total[k], e, label=math_label(norm), **curve_style(i))
        # markers only: a level's own time need not grow with the level on the coarsest ones (form
        # compilation), and a line through them would double back
        right.loglog([rows[j]["time_s"] for j in k], e, label=math_label(norm), **dict(curve_style(i), linestyle="none"))
    left.set_xlabel("cumulative wall time [s]")
    right.set_xlabel("wall time of the level [s]")
    left.set_ylabel("error")
    left.legend(loc="best")
    _finish(fig, left, title)
    return fig


def newton(studies, title=""):
    """Newton iterations per level against the number of unknowns ({label: rows}; one study: label
    ""), levels that did not converge marked with a red ×."""
    fig, ax = _figure()
    failed_label = "not converged"
    for i, (label, rows) in enumerate(studies.items()):
        ax.semilogx([row["dofs"] for row in rows], [row["newton_its"] for row in rows],
                    label=label or None, **curve_style(i))
        failed = [row for row in rows if not row["converged"]]
        if failed:
            ax.plot([row["dofs"] for row in failed], [row["newton_its"] for row in failed], "x",
                    color="#CC0000", markersize=10, markeredgewidth=2, label=failed_label, zorder=3)
            failed_label = None  # one legend entry for all studies
    _integer_axis(ax)
    ax.set_xlabel("degrees of freedom")
    ax.set_ylabel("Newton iterations")
    if ax.get_legend_handles_labels()[1]:
        ax.legend(loc="best")
    _finish(fig, ax, title)
    return fig


# --- several studies ----------------------------------------------------------------------------

def compare_convergence(studies):
    """One panel per norm, every study's error against h in it."""
    return _compare(studies, lambda rows, norm: error_curves(rows).get(norm),
                    r"mesh size $h$ (largest cell diameter)", fitted=True)


def compare_work_precision(studies):
    """One panel per norm, every study's error against its cumulative wall time."""
    def curve(rows, norm):
        total = np.cumsum([row["time_s"] or 0.0 for row in rows])
        k = [j for j, row in enumerate(rows) if row["converged"] and row.get(norm) is not None]
        return (total[k], np.array([rows[j][norm] for j in k])) if k else None
    return _compare(studies, curve, "cumulative wall time [s]", fitted=False)


def _compare(studies, curve, xlabel, fitted):
    all_norms = list(dict.fromkeys(norm for rows in studies.values() for norm in norms(rows)))
    if not all_norms:
        return None
    fig, axes = _figure(ncols=len(all_norms), width=WIDTH * 0.85 * len(all_norms), squeeze=False)
    for ax, norm in zip(axes[0], all_norms):
        for i, (label, rows) in enumerate(studies.items()):
            xy = curve(rows, norm)
            if xy is None or not len(xy[0]):
                continue
            slope = fitted_slope(*xy) if fitted else None
            ax.loglog(*xy, label=label + (f" ({slope:.2f})" if slope is not None else ""), **curve_style(i))
        ax.set_xlabel(xlabel)
        ax.set_ylabel(math_label(norm))
        ax.legend(loc="best", title="fitted slope in ( )" if fitted else None, title_fontsize=8)
        readable_log_axis(ax.xaxis)
    fig.tight_layout()
    return fig


# --- pieces -------------------------------------------------------------------------------------

def _triangle_kind(is_proven):
    what = "triangles" if len(is_proven) > 1 else "triangle"
    if all(is_proven):
        return f"{what}: proven rate{'s' if len(is_proven) > 1 else ''}"
    fitted = f"fitted over the last {FIT_LEVELS} levels"
    return f"{what}: proven rate, else slope {fitted}" if any(is_proven) else f"{what}: slope {fitted}"


def error_curves(rows):
    """{norm: (h, error)} over the converged levels that measured it; norms with no point left out."""
    curves = {}
    for norm in norms(rows):
        points = [(row["h"], row[norm]) for row in rows if row["converged"] and row.get(norm)]
        if points:
            curves[norm] = tuple(np.array(v, dtype=float) for v in zip(*points))
    return curves


def slope_triangle(ax, h, e, rate, above=False, colour="black"):
    """A triangle of slope `rate` beside the finest segment of the curve (h, e), legs labelled 1 and rate.
    Below the curve (right angle bottom right) or above it (right angle top left)."""
    h_a, h_b, e_a, e_b = h[-1], h[-2], e[-1], e[-2]
    x_c, y_c = math.sqrt(h_a * h_b), math.sqrt(e_a * e_b)
    half = (h_b / h_a) ** 0.3  # the triangle spans 60 % of the last segment in log h
    x0, x1 = x_c / half, x_c * half
    gap = 2.2 if above else 1 / 2.2  # off the curve by a factor 2.2 in the error
    y0 = y_c * gap / half ** rate
    y1 = y0 * (x1 / x0) ** rate
    corner = (x0, y1) if above else (x1, y0)
    ax.update_datalim([(x0, y0 / 1.7), (x1, y1 * 1.7)])  # keep the leg labels inside the axes
    ax.autoscale_view()
    from matplotlib.colors import to_rgba
    ax.fill([x0, corner[0], x1], [y0, corner[1], y1], facecolor=to_rgba(colour, 0.12), edgecolor=colour,
            linewidth=0.9, zorder=1)
    x_mid, y_mid = math.sqrt(x0 * x1), math.sqrt(y0 * y1)
    text = dict(color=colour, fontsize=9)
    if above:
        ax.text(x_mid, y1 * 1.12, "1", ha="center", va="bottom", **text)
        ax.text(x0 / 1.06, y_mid, _rate_text(rate), ha="right", va="center", **text)
    else:
        ax.text(x_mid, y0 / 1.12, "1", ha="center", va="top", **text)
        ax.text(x1 * 1.06, y_mid, _rate_text(rate), ha="left", va="center", **text)


def _rate_text(rate):
    return f"{rate:g}" if abs(rate - round(rate, 2)) < 1e-12 else f"{rate:.2f}"


def math_label(norm):
    """The norm's label in math notation for matplotlib (mathtext), or its column name."""
    if norm not in LABELS:
        return norm.replace("_", " ")
    return "$" + LABELS[norm][1].replace(r"\|", r"\Vert ") + "$"  # mathtext draws \| as a single bar


def curve_style(i):
    """Colour, marker and line style of the i-th curve: distinguishable in grey print too."""
    return {"color": COLOURS[i % len(COLOURS)], "marker": MARKERS[i % len(MARKERS)],
            "linestyle": LINESTYLES[i % len(LINESTYLES)]}


def _figure(ncols=1, width=WIDTH, sharey=False, squeeze=True):
    """A figure on the Agg canvas: no pyplot, no display, no global backend switch."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=(width, HEIGHT))
    return fig, fig.subplots(1, ncols, sharey=sharey, squeeze=squeeze)


def _grid(panels):
    """A figure with `panels` axes, GRID_COLUMNS per row, as a flat list (unused cells removed)."""
    if panels == 1:
        fig, ax = _figure()
        return fig, [ax]
    from matplotlib.figure import Figure
    ncols = min(GRID_COLUMNS, panels)
    nrows = -(-panels // ncols)  # ceiling division
    fig = Figure(figsize=(0.75 * WIDTH * ncols, 0.8 * HEIGHT * nrows))
    axes = list(fig.subplots(nrows, ncols, squeeze=False).flat)
    for ax in axes[panels:]:
        ax.remove()
    return fig, axes[:panels]


def _integer_axis(ax):
    from matplotlib.ticker import MaxNLocator
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_ylim(0, ax.get_ylim()[1] + 0.8)  # room above the highest point


def readable_log_axis(axis):
    """On a log axis spanning less than 2.5 decades, ticks at 1, 2, 5 × 10^k labelled as plain numbers
    (matplotlib would label one or two powers of ten only)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter
    low, high = sorted(axis.get_view_interval())
    if low <= 0 or math.log10(high / low) >= 2.5:
        return
    axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    axis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    axis.set_minor_formatter(NullFormatter())


def _finish(fig, ax, title):
    for axes in fig.axes:
        if axes.get_xscale() == "log":
            readable_log_axis(axes.xaxis)
    if title and len(fig.axes) == 1:
        ax.set_title(title)
    elif title:
        fig.suptitle(title, fontsize=9.5)
    fig.tight_layout()


def model_error(rows, path):
    """The model-error figure of `rows` (one mesh of an ε-sweep) as `path` (its suffix picks the format)."""
    with styled():
        model_error_figure(rows).savefig(path)
    return path


def model_error_figure(rows):
    """H1 and L2 model error against ε, one curve per α, log-log, with the slope 1/α over the smaller
    half of the sweep; a Figure on the Agg canvas (no pyplot)."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=(2 * WIDTH, HEIGHT))
    for ax, norm, label in zip(fig.subplots(1, 2), ("H1", "L2"), (r"$|u_{\varepsilon,h}-u_{S,h}|_{H^1}$",
                                                                  r"$\|u_{\varepsilon,h}-u_{S,h}\|_{L^2}$")):
        for k, alpha in enumerate(sorted({r["alpha"] for r in rows})):
            curve = [r for r in rows if r["alpha"] == alpha and r[norm] is not None]
            eps, err = [r["epsilon"] for r in curve], [r[norm] for r in curve]
            style = curve_style(k)
            ax.loglog(eps, err, color=style["color"], marker=style["marker"], label=rf"$\alpha = {alpha:g}$")
            tail = eps[len(eps) // 2:]  # through the last point
            ax.loglog(tail, [err[-1] * (e / eps[-1]) ** (1 / alpha) for e in tail], ls=":", lw=2,
                      color=style["color"], label=rf"slope $1/{alpha:g}$")
        ax.set_xlabel(r"penalty parameter $\varepsilon$")
        ax.set_ylabel(label)
        ax.legend(fontsize=8)
    fig.suptitle(f"Model error of the compliance model on the fixed mesh N = {rows[0]['N']}", fontsize=9.5)
    fig.tight_layout()
    return fig
