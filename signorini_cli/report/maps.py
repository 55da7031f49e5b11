"""A rate map's outputs: map.csv, a heat map per norm and pair of varied keys (fitted − proven rate,
the verdict as a marker), line plots of the rate against one key, map.tex and the terminal summary."""
import itertools
import math
from pathlib import Path

from ..record import csvfile
from ..studies import rate_map
from ..system import files
from ..config import names
from . import latex, plots

MAP_FILE = "map.csv"
TERMINAL_WIDTH = 120
# the verdict classes of analysis.verdict, each with a marker that reads in grey print too
VERDICT_MARKERS = {"agrees": "o", "exceeds": "^", "below": "v", "below theory": "v", "inconclusive": "x",
                   "not covered": "", "no rate": "x"}
VERDICT_SHORT = {"agrees": "ok", "exceeds": "exc", "below": "low", "below theory": "low", "inconclusive": "?",
                 "not covered": "n/c", "no rate": "-"}
SPAN = 1.0  # the colour scale of fitted − proven: ±1 (a whole order of h) saturates
MAX_LINES = 7  # curves in one line plot (plots.COLOURS)


def write(folder, rows, varied, draw=True):
    """map.csv, map.md and map.tex in `folder`, with the figures unless draw is False; the paths."""
    folder = Path(folder)
    norms = rate_map.norms_of(rows)
    shown = shown_norms(norms)
    texts = {MAP_FILE: csvfile.text(rows, rate_map.columns(varied, norms)),
             "map.tex": latex_table(rows, varied, shown), "map.md": markdown_table(rows, varied, shown)}
    files.replace_all([(folder / name, lambda path, text=text: path.write_text(text)) for name, text in texts.items()])
    written = [folder / name for name in texts]
    if draw:  # heat maps for every norm with a verdict somewhere, rate lines for those shown
        judged = [n for n in norms if any(r.get(f"verdict_{n}") not in (None, "", "no rate", "not covered")
                  for r in rows)]
        written += figures(folder, rows, varied, shown, judged)
    return written


# --- text ----------------------------------------------------------------------------------------

def _cell(value):
    if value is None or value == "":
        return "-"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _rate(value):
    return "-" if value is None or value == "" else f"{float(value):.2f}"


def rate_cell(row, norm):
    """The fitted rate with its interval when it has one: 2.01 [1.98, 2.04]."""
    rate, lo, hi = (row.get(f"rate_{norm}{s}") for s in ("", "_lo", "_hi"))
    if rate in (None, "") or lo in (None, "") or hi in (None, "") or float(lo) == float(hi):
        return _rate(rate)
    return f"{_rate(rate)} [{_rate(lo)}, {_rate(hi)}]"


def summary_rows(rows, varied, norms):
    """The terminal table: point, values, per norm rate (interval), proven, verdict; converged, time."""
    head = ["#"] + list(varied) + [x for n in norms for x in (f"rate {n}", "proven", "verdict")] + ["conv", "time_s"]
    body = []
    for k, row in enumerate(rows):
        cells = [str(k)] + [_cell(row.get(key)) for key in varied]
        for n in norms:
            cells += [rate_cell(row, n), _rate(row.get(f"proven_{n}")), _cell(row.get(f"verdict_{n}"))]
        cells += ["yes" if row.get("converged") in (True, "true") else "no", f"{float(row.get('time_s') or 0):.1f}"]
        body.append(cells)
    return head, body


def shown_norms(norms):
    """The norms the tables and figures show: L2 and H1 (map.csv has every measured one), else all."""
    return [n for n in norms if n in rate_map.NORMS] or list(norms)


def summary(rows, varied, title=""):
    """The map as a right-aligned table within TERMINAL_WIDTH columns (the L2 rate alone when wider)."""
    norms = shown_norms(rate_map.norms_of(rows))
    for shown in (norms, norms[:1]):
        head, body = summary_rows(rows, varied, shown)
        lines = _aligned([head] + body)
        if max(map(len, lines)) <= TERMINAL_WIDTH:
            break
    lines = [line[:TERMINAL_WIDTH] for line in lines]
    failed = [f"  point {k}: {row['status']}" for k, row in enumerate(rows) if row.get("status") != "complete"]
    return "\n".join(([title] if title else []) + lines + [line[:TERMINAL_WIDTH] for line in failed])


def _aligned(table):
    widths = [max(len(r[i]) for r in table) for i in range(len(table[0]))]
    return ["  ".join(c.rjust(w) for c, w in zip(r, widths)) for r in table]


def point_line(k, count, row):
    """One line as a point ends: its values, per norm rate and verdict, time (within TERMINAL_WIDTH)."""
    norms = shown_norms(rate_map.norms_of([row]))
    values = ", ".join(f"{key}={_cell(row[key])}" for key in row if key in _varied(row))
    rates = ", ".join(f"{n} {rate_cell(row, n)} {_cell(row.get(f'verdict_{n}'))}" for n in norms)
    status = "" if row["status"] == "complete" else f" [{row['status']}]"
    # numbered from 0 like the map's table, its folders and --points: "point 3 of 0-3"
    return f"point {k} of 0-{count - 1} ({values}): {rates}; {float(row['time_s']):.1f} s{status}"[:TERMINAL_WIDTH]


def _varied(row):
    """The leading columns of a map row: its varied keys."""
    keys = []
    for key in row:
        if key.startswith(("rate_", "proven_")) or key in rate_map.TAIL_COLUMNS:
            break
        keys.append(key)
    return keys


def markdown_table(rows, varied, norms):
    head, body = summary_rows(rows, varied, norms)
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    return "\n".join(lines + ["| " + " | ".join(cells) + " |" for cells in body]) + "\n"


KEYS_TEX = {"alpha": r"$\alpha$", "epsilon.theta": r"$\theta$", "epsilon.p": "$p$", "dimension": "$d$",
            "element.degree": "degree"}  # a varied config key as the caption's formula names it


def latex_table(rows, varied, norms):
    """map.tex: one booktabs float with a \\label, the varied keys as their symbols, per norm (written out)
    the fitted rate, the proven rate and the verdict (abbreviated, the key in the caption); split by norms
    where it does not fit \\textwidth."""
    lead = [(KEYS_TEX.get(k, latex.escape(k)), [latex.escape(_cell(row.get(k))) for row in rows]) for k in varied]
    cells = []
    for n in norms:
        cells += [("fit", [_latex_rate(row.get(f"rate_{n}")) for row in rows]),
                  ("proven", [_latex_rate(row.get(f"proven_{n}")) for row in rows]),
                  ("", [VERDICT_SHORT.get(row.get(f"verdict_{n}"), latex.escape(_cell(row.get(f"verdict_{n}"))))
                        for row in rows])]
    key = "; ".join(f"{s}: {v}" for v, s in VERDICT_SHORT.items() if v in ("agrees", "exceeds", "below",
                                                                            "inconclusive", "not covered"))
    caption = ("Rate map: for each " + ", ".join(head for head, _ in lead) + ", the slope of $\\log e$ against "
               "$\\log h$ fitted over the finest levels, the rate the paper proves, and the verdict (" +
               latex.escape(key) + ").")
    return "% rate map written by signorini; needs \\usepackage{booktabs}\n" + latex.table(
        lead + cells, [(names.name(n).tex, 3) for n in norms], caption, latex.label("map"), len(rows),
        align="r" * len(lead) + "rrl" * len(norms))


def _latex_rate(value):
    return "--" if value is None or value == "" else latex.rate(float(value))


# --- figures ------------------------------------------------------------------------------------

def _number(value):
    try:
        return float(value)
    except (TypeError, ValueError):
        return None


def _axis_values(rows, key):
    """The distinct values of a key in map order, and whether a log axis suits them."""
    values = list(dict.fromkeys(_cell(row.get(key)) for row in rows))
    numbers = [_number(v) for v in values]
    numeric = all(x is not None for x in numbers)
    if numeric:
        values = [v for _, v in sorted(zip(numbers, values))]
    logarithmic = numeric and min(numbers) > 0 and max(numbers) / min(numbers) >= 100
    return values, numeric, logarithmic


def _fixed(rows, keys):
    """The combinations of `keys` present in the rows, in map order."""
    return list(dict.fromkeys(tuple(_cell(row.get(k)) for k in keys) for row in rows))


def figures(folder, rows, varied, norms, judged=None):
    """heat_<norm>_<a>_<b> per norm of `judged` (default: `norms`; those with a verdict) and pair of varied
    keys (one panel per value of the other keys), rate_<norm>_<key> per norm and key: PNG and PDF; the paths."""
    written = []
    with plots.styled():
        for norm in norms if judged is None else judged:
            for a, b in itertools.combinations(varied, 2):
                fig = heat_map(rows, norm, a, b, [k for k in varied if k not in (a, b)])
                written += plots.save(fig, folder, f"heat_{norm}_{_name(a)}_{_name(b)}")
        for norm in norms:
            for key in varied:
                fig = rate_lines(rows, norm, key, [k for k in varied if k != key])
                written += plots.save(fig, folder, f"rate_{norm}_{_name(key)}")
    return written


def _key(key):
    """A varied key on an axis: its symbol (θ, α) as mathtext, else its name."""
    return KEYS_TEX.get(key, key)


def _values(pairs):
    """Fixed keys in a title or legend: θ = 0.1, α = 2."""
    return ", ".join(f"{_key(k)[:-1]} = {v}$" if _key(k).endswith("$") else f"{k} = {v}" for k, v in pairs)


def _name(key):
    return key.replace(".", "-")


def heat_map(rows, norm, a, b, others):
    """Fitted − proven rate of `norm` on the grid of keys a (x) and b (y), a panel per combination of
    the other keys; diverging colours centred at 0, the verdict as a marker, `not covered` grey."""
    from matplotlib.colors import TwoSlopeNorm
    from matplotlib.figure import Figure
    xs, ys = _axis_values(rows, a)[0], _axis_values(rows, b)[0]
    combos = _fixed(rows, others)
    per_row = max(1, min(len(combos), 2))
    n_rows = math.ceil(len(combos) / per_row)
    left, right, top, gap, below = 0.7, 0.85, 0.3, 0.75, 0.75  # inches: tick labels, colour bar, titles, legend
    width = plots.WIDTH_PT / plots.PT_PER_INCH
    panel_w = (width - left - right - (per_row - 1) * 0.5) / per_row
    panel_h = max(0.9, 0.22 * len(ys) + 0.2)
    height = top + n_rows * panel_h + (n_rows - 1) * gap + below
    fig = Figure(figsize=(width, height))  # no pyplot: no GUI backend, no global figure state
    colour, image = TwoSlopeNorm(0.0, -SPAN, SPAN), None
    for n, combo in enumerate(combos):
        r, c = divmod(n, per_row)
        ax = fig.add_axes([(left + c * (panel_w + 0.5)) / width,
                           1 - (top + r * (panel_h + gap) + panel_h) / height, panel_w / width, panel_h / height])
        image = _heat_panel(ax, rows, norm, (a, xs), (b, ys), dict(zip(others, combo)), colour)
        ax.set_title(", ".join(filter(None, [plots.math_label(norm), _values(zip(others, combo))])),
                     fontsize=plots.FONT_PT)
    bar_axes = fig.add_axes([(width - right + 0.15) / width, below / height, 0.1 / width,
                             (height - top - below) / height])
    fig.colorbar(image, cax=bar_axes, extend="both").set_label("fitted $-$ proven rate")  # the title names the norm
    _verdict_legend(fig)
    return fig


def _heat_panel(ax, rows, norm, x, y, fixed, colour):
    import numpy as np
    (a, xs), (b, ys) = x, y
    grid = np.full((len(ys), len(xs)), np.nan)
    for row in rows:
        if any(_cell(row.get(k)) != v for k, v in fixed.items()):
            continue
        i, j = ys.index(_cell(row.get(b))), xs.index(_cell(row.get(a)))
        rate, proven = _number(row.get(f"rate_{norm}")), _number(row.get(f"proven_{norm}"))
        verdict = row.get(f"verdict_{norm}") or "no rate"
        if rate is not None and proven is not None:
            grid[i, j] = rate - proven
        else:
            ax.add_patch(_grey(j, i))
        marker = VERDICT_MARKERS.get(verdict, "x")
        if marker:
            ax.plot(j, i - 0.22, marker, ms=3, mfc="none", mec="black", mew=0.6)
        if rate is not None:
            ax.text(j, i + 0.12, f"{rate:.2f}", ha="center", va="center", fontsize=6)
    image = ax.imshow(np.ma.masked_invalid(grid), cmap="RdBu", norm=colour, origin="lower", aspect="auto")
    ax.set_xticks(range(len(xs)), xs)
    ax.set_yticks(range(len(ys)), ys)
    ax.set_xlabel(_key(a))
    ax.set_ylabel(_key(b))
    ax.grid(False)
    ax.set_xlim(-0.5, len(xs) - 0.5)
    ax.set_ylim(-0.5, len(ys) - 0.5)
    return image


def _grey(j, i):
    from matplotlib.patches import Rectangle
    return Rectangle((j - 0.5, i - 0.5), 1, 1, facecolor="0.8", edgecolor="none", zorder=0)


def _verdict_legend(fig):
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    handles = [Line2D([], [], ls="none", marker=m, mfc="none", mec="black", ms=4, label=v)
               for v, m in VERDICT_MARKERS.items() if v in ("agrees", "exceeds", "below", "inconclusive")]
    handles.append(Patch(facecolor="0.8", label="not covered"))
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), frameon=False,
               fontsize=plots.FONT_PT - 1, borderaxespad=0.1)


def rate_lines(rows, norm, key, others):
    """The fitted rate of `norm` against `key`, one curve per combination of the other keys (at most
    MAX_LINES: the first ones in map order), its proven rate dotted in the same colour."""
    from matplotlib.figure import Figure
    xs, numeric, logarithmic = _axis_values(rows, key)
    combos = _fixed(rows, others)[:MAX_LINES]
    fig = Figure(figsize=(plots.WIDTH_PT / plots.PT_PER_INCH, 2.6))
    ax = fig.add_subplot()
    fig.subplots_adjust(left=0.12, right=0.97, bottom=0.16, top=0.91)
    for i, combo in enumerate(combos):
        fixed = dict(zip(others, combo))
        chosen = {_cell(r.get(key)): r for r in rows if all(_cell(r.get(k)) == v for k, v in fixed.items())}
        at = [x for x in xs if x in chosen]
        where = [float(x) if numeric else xs.index(x) for x in at]
        colour, marker = plots.COLOURS[i % len(plots.COLOURS)], plots.MARKERS[i % len(plots.MARKERS)]
        label = _values(fixed.items()) or plots.math_label(norm)
        ax.plot(where, [_number(chosen[x].get(f"rate_{norm}")) or math.nan for x in at], marker=marker,
                color=colour, label=label)
        logs = [_number(chosen[x].get(f"rate_{norm}_log")) or math.nan for x in at]
        if not all(math.isnan(p) for p in logs):
            ax.plot(where, logs, "--", marker=marker, mfc="none", color=colour)  # the fit of e/|ln h|
        ax.plot(where, [_number(chosen[x].get(f"proven_{norm}")) or math.nan for x in at], ":", marker="_",
                ms=8, color=colour)
    if logarithmic:
        ax.set_xscale("log")
    if not numeric:
        ax.set_xticks(range(len(xs)), xs)
    ax.set_xlabel(_key(key))
    logs = any(_number(r.get(f"rate_{norm}_log")) is not None for r in rows)
    ax.set_ylabel(f"fitted rate, {plots.math_label(norm)}" + (r" (dashed: fit of $e/|\ln h|$)" if logs else ""))
    ax.set_title("dotted: the proven rate" + ("; solid: plain slope" if logs else ""), fontsize=plots.FONT_PT)
    if len(combos) > 1 or others:
        ax.legend(loc="best", fontsize=plots.FONT_PT - 1)
    return fig
