"""Human-readable output: the terminal table, Markdown/LaTeX tables and the figures of a study of any type
(what its type says it reports)."""
from pathlib import Path

from .. import studies
from ..analysis import verdict
from ..analysis.rates import fitted
from ..analysis.rates import error_columns as norms  # the measured norms of a table, for report, plots, progress
from ..config import ConfigError, names
from . import plots as plotting  # its matplotlib import waits inside its functions

COLUMN_SETS = ("paper", "all")  # output.columns / report --columns, besides a list of columns
PAPER_LEADING = ("N", "h", "epsilon", "newton_its")  # what a paper shows before the errors
TERMINAL_WIDTH = 120
FORMATS = {"h": ".3e", "epsilon": ".3e", "time_s": ".2f"}
# gmsh/file meshes: their size spread and Γ_C, as in the CSV
FORMATS.update({"h_min": ".3e", "gamma_c_measure": ".6f", "gamma_c_quasi_uniformity": ".3f", "alpha": "g", "p": "g"})
FIT_LEVELS = 3  # fitted slopes without a config: verification.fit_levels' default
RATE_DEFINITION = r"rate: $\log(e_k/e_{k-1})/\log(h_k/h_{k-1})$ between successive levels"


def fitted_slope(h, e, k=FIT_LEVELS):
    """Least-squares slope of log e against log h over the last k points (None with fewer than 2)."""
    return fitted(list(h), list(e), [True] * len(e), k)


# --- which columns a table shows --------------------------------------------------------------

def choose(rows, columns="paper", proven=None):
    """(leading columns, norms) of a table: "paper" = N, h, ε, Newton and the norms the paper bounds
    for the scene (`proven`; without it L2 and H1), "all" = every column, or a list of column names."""
    if not rows:
        return [], []
    measured = norms(rows)
    if columns == "all":
        return [c for c in rows[0] if c not in measured and not c.startswith("rate_") and c != "reason"], measured
    if columns == "paper":  # h goes when N gives it (h = c/N on every level): the caption says c
        lead = [c for c in PAPER_LEADING if c in rows[0] and not (c == "h" and h_per_N(rows))]
        return lead, paper_norms(measured, proven or {})
    unknown = [c for c in columns if c not in rows[0]]
    if unknown:
        raise ConfigError("output.columns", f"{unknown[0]!r} is not a column of this study; it has "
                                            + ", ".join(c for c in rows[0] if not c.startswith("rate_")))
    return [c for c in columns if c not in measured], [c for c in columns if c in measured]


def paper_norms(measured, proven):
    """The measured norms with a proven rate, pos_gc_scaled left out beside pos_gc (a power of it,
    Corollary 3.2 ii); with no proven rate known, the first two measured (L2, H1)."""
    shown = [n for n in measured if n in proven and not (n == "pos_gc_scaled" and "pos_gc" in proven)]
    return shown or measured[:2]


def h_per_N(rows):
    """c when h = c/N on every level (the structured meshes: N cells per side), else None."""
    products = [row["h"] * row["N"] for row in rows if row.get("h") and row.get("N")]
    if len(products) != len(rows) or not products:
        return None
    return products[0] if max(products) - min(products) <= 1e-9 * products[0] else None


def _columns_of(cfg, columns):
    if columns is not None:
        return columns
    return cfg.output.columns if cfg is not None else "paper"


# --- the terminal table -------------------------------------------------------------------------

def format_table(rows, cfg=None, columns=None):
    """The rate table for the terminal, right-aligned, each norm's error (.3e) and rate (.2f) under its
    short name, '-' where undefined; by default the paper's columns and the time (< 120 characters)."""
    if not rows:
        return "(no levels)"
    chosen = _columns_of(cfg, columns)
    lead, shown = choose(rows, chosen, proven_rates(cfg))
    if chosen == "paper":
        lead = lead + ["time_s"]
    def label(column):  # short names for the paper's columns, the CSV's names for the others
        return names.name(column).text if chosen == "paper" else column
    groups = [("", [(label(c), [_format(c, r.get(c)) for r in rows]) for c in lead])]
    groups += [(label(n), [("error", [_format(n, r.get(n)) for r in rows]),
                                     ("rate", [_format("rate_", r.get(f"rate_{n}")) for r in rows])])
               for n in shown]
    return "\n".join(_aligned(groups) + _failures(rows, end=""))


def _aligned(groups):
    """Lines of a right-aligned table whose column groups [(title, [(header, cells)])] get their title
    centred above them (a title line only when some group has one)."""
    widths = [[max(len(header), *map(len, cells)) for header, cells in columns] for _, columns in groups]
    spans = [sum(w) + 2 * (len(w) - 1) for w in widths]
    spans = [max(span, len(title)) for span, (title, _) in zip(spans, groups)]
    widths = [w[:-1] + [w[-1] + span - sum(w) - 2 * (len(w) - 1)] for w, span in zip(widths, spans)]
    lines = ["    ".join(title.center(span) for (title, _), span in zip(groups, spans))]
    n = len(groups[0][1][0][1])
    for k in range(-1, n):
        lines.append("    ".join("  ".join((header if k < 0 else cells[k]).rjust(w)
                                             for (header, cells), w in zip(columns, ws))
                                   for (_, columns), ws in zip(groups, widths)))
    return [line.rstrip() for line in lines if line.strip()] if any(t for t, _ in groups) else lines[1:]


def _format(column, value):
    if value is None:
        return "-"
    if isinstance(value, bool):
        return ("yes" if value else "NO") if column == "converged" else ("yes" if value else "no")
    if column.startswith(("rate_", "fit_")):  # fit_: the fitted slopes of the ε → 0 tables
        return f"{value:.2f}"
    if column in FORMATS:
        return f"{value:{FORMATS[column]}}"
    if isinstance(value, float):
        return f"{value:.3e}"
    return str(value)


def summary_table(studies, fit_levels=FIT_LEVELS):
    """One line per study ({label: rows}): levels, finest h, per norm (under its name) the finest error
    and the slope fitted over the last `fit_levels` levels, total wall time."""
    all_norms = list(dict.fromkeys(norm for rows in studies.values() for norm in norms(rows)))
    ok = {label: [row for row in rows if row["converged"]] for label, rows in studies.items()}
    lead = [("study", list(studies)), ("levels", [str(len(rows)) for rows in studies.values()]),
            ("finest h", [f"{rows[-1]['h']:.3e}" if rows else "-" for rows in ok.values()]),
            ("time_s", [f"{sum(row['time_s'] or 0.0 for row in rows):.2f}" for rows in studies.values()])]
    groups = [("", lead)]
    for norm in all_norms:
        points = [[(row["h"], row[norm]) for row in rows if row.get(norm)] for rows in ok.values()]
        groups.append((names.name(norm).text, [
            ("finest", [f"{p[-1][1]:.3e}" if p else "-" for p in points]),
            ("fit", [_rate(fitted_slope(*zip(*p), k=fit_levels) if len(p) > 1 else None, "-") for p in points])]))
    return "\n".join(_aligned(groups))


# --- tables for papers and notebooks (deal.II ConvergenceTable style: error, then its rate) ----

def markdown_table(rows, digits=3, columns="paper", proven=None):
    """The rate table as GitHub Markdown: errors in scientific notation with `digits`, rates .2f; each
    norm's two columns headed "<name> error", "<name> rate"."""
    lead, shown = choose(rows, columns, proven)
    header = [names.name(c).text for c in lead] + [f"{names.name(n).text} {k}" for n in shown
                                                   for k in ("error", "rate")]
    lines = ["| " + " | ".join(header) + " |", "|" + "---:|" * len(header)]
    for row in rows:
        cells = [_paper_cell(c, row, digits, _scientific, "–") for c in lead]
        for norm in shown:
            cells += [_paper_cell(norm, row, digits, _scientific, "–"), _rate(row.get(f"rate_{norm}"), "–")]
        lines.append("| " + " | ".join(cells) + " |")
    notes = _failures(rows)
    return "\n".join(lines + ([""] + notes if notes else [])) + "\n"  # a blank line ends the table


def latex_table(rows, digits=3, caption="", columns="paper", proven=None):
    """The rate table as a booktabs `table` float (needs \\usepackage{booktabs}): "error | rate" under
    each norm's short name, the definitions in the caption; numbers as 2.303e-2."""
    lead, shown = choose(rows, columns, proven)
    first = len(lead) + 1
    lines = [r"\begin{table}", r"\centering", r"\setlength{\tabcolsep}{3pt}",
             r"\caption{" + _caption(caption, lead, shown, rows) + "}",
             r"\begin{tabular}{" + "r" * len(lead) + "rr" * len(shown) + "}", r"\toprule"]
    if shown:
        lines.append(" & ".join([""] * len(lead) + [rf"\multicolumn{{2}}{{c}}{{{names.name(n).tex}}}"
                                                     for n in shown]) + r" \\")
        lines.append(" ".join(rf"\cmidrule(lr){{{first + 2 * i}-{first + 2 * i + 1}}}" for i in range(len(shown))))
    lines += [" & ".join([names.name(c).tex for c in lead] + ["error", "rate"] * len(shown)) + r" \\",
              r"\midrule"]
    for row in rows:
        cells = [_paper_cell(c, row, digits, _latex_number, "--") for c in lead]
        for norm in shown:
            cells += [_paper_cell(norm, row, digits, _latex_number, "--"), _rate(row.get(f"rate_{norm}"), "--")]
        lines.append(" & ".join(cells) + r" \\")
    lines += [r"\bottomrule", r"\end{tabular}", r"\end{table}"]
    return "\n".join(lines) + "\n"


def _caption(caption, lead, shown, rows):
    """The caption: the study, then what each short name means, the rate, and the failed levels."""
    defined = [f"{names.name(c).tex}: {names.name(c).definition}" for c in lead + shown]
    if "N" in lead and "h" not in lead and h_per_N(rows):
        defined.insert(1, f"$h = {h_per_N(rows):.4g}/N$, the largest cell diameter")
    text = (_tex_escape(caption) + ". " if caption else "") + "; ".join(
        defined + ([RATE_DEFINITION] if shown else [])) + "."
    return " ".join([text] + [_tex_escape(line) for line in _failures(rows)])


# plain text (a study's name and description) in LaTeX: the specials escaped, the usual Unicode as math
TEX_TEXT = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
            "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}",
            "α": r"$\alpha$", "ε": r"$\varepsilon$", "θ": r"$\theta$", "Γ": r"$\Gamma$", "π": r"$\pi$",
            "δ": r"$\delta$", "Ω": r"$\Omega$", "≥": r"$\geq$", "≤": r"$\leq$", "→": r"$\to$", "−": "-",
            "×": r"$\times$", "²": r"$^2$", "³": r"$^3$", "·": r"$\cdot$", "–": "--", "—": "---"}


def _tex_escape(text):
    return "".join(TEX_TEXT.get(char, char if char.isascii() else "?") for char in text)


def _paper_cell(column, row, digits, scientific, missing):
    value = row.get(column)
    if column == "newton_its" and not row["converged"]:
        return f"{value} (failed)"
    if value is None:
        return missing
    if isinstance(value, bool):
        return "yes" if value else "no"
    return scientific(value, digits) if isinstance(value, float) else str(value)


def _rate(value, missing):
    return missing if value is None else f"{value:.2f}"


def _scientific(value, digits):
    return f"{value:.{digits}e}"


def _latex_number(value, digits):
    """2.303e-2: the narrowest notation a reader knows ($m \\cdot 10^{k}$ would not fit the page)."""
    mantissa, exponent = f"{value:.{digits}e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def _failures(rows, end="."):
    """One line per row that did not converge: its level (a sweep's: its N, α and ε)."""
    return [f"{_which(row)} did not converge: {row.get('reason')}{end}" for row in rows if row.get("converged") is False]


def _which(row):
    if "level" in row:
        return f"Level {row['level']} (N = {row['N']})"
    return "Solve " + ", ".join(f"{names.name(k).text} = {row[k]:g}" for k in ("N", "alpha", "epsilon") if k in row)


# --- everything a study leaves besides rates.csv and study.h5 -----------------------------------

def write(study, cfg=None, digits=3, plots=True, folder=None, columns=None, figure=None):
    """The tables (<name>.md, <name>.tex) and (if `plots`) the figures a study of its type reports, into
    `folder`; the paths written. `columns` as output.columns for its rate tables (default: the config's,
    else "paper"); `figure`: plots.Layout options."""
    folder = Path(folder or study.folder)
    shown, figures = studies.of(study.study_type).reported(cfg, study.tables or {"rates": study.rows})
    caption = f"Study {study.name}" + (f": {cfg.description}" if cfg is not None and cfg.description else "")
    chosen, proven = _columns_of(cfg, columns), proven_rates(cfg)
    written = []
    for table in shown:
        path = folder / table.name
        path.parent.mkdir(parents=True, exist_ok=True)
        how = (chosen, proven) if table.paper else ("all", {})
        label = caption + ("" if table.paper and "/" not in table.name else f", table {table.name}")
        written.append(path.with_name(path.name + ".md"))
        written[-1].write_text(f"<!-- {label} -->\n" + markdown_table(table.rows, digits, *how))
        written.append(path.with_name(path.name + ".tex"))
        written[-1].write_text(latex_table(table.rows, digits, label, *how))
    if plots:
        written += draw(figures, study, cfg, folder, proven, figure)
    return written


def draw(figures, study, cfg, folder, proven, figure=None):
    """The study type's figures, each by its kind; the paths written."""
    fit_levels = cfg.verification.fit_levels if cfg is not None else FIT_LEVELS
    figure = dict({"width": cfg.output.figure_width or None} if cfg is not None else {}, **(figure or {}))
    written = []
    for fig in figures:
        if fig.kind == "convergence" and fig.data:
            written += plotting.write_all(fig.data, (folder / fig.name).parent, proven=proven,
                                          title=title(study, cfg), fit_levels=fit_levels, **figure)
        elif fig.kind == "model_error":
            written += [plotting.model_error(fig.data, folder / f"{fig.name}{suffix}", figure.get("width") or
                                             plotting.WIDTH_PT) for suffix in (".png", ".pdf")]
        elif fig.kind == "comparison":
            written += plotting.write_comparison(fig.data, folder, fit_levels, figure.get("width"))
    return written


def terminal(study, cfg=None):
    """What a run or `report` prints of a study: its rate tables as format_table, its other tables whole."""
    shown, _ = studies.of(study.study_type).reported(cfg, study.tables or {"rates": study.rows})
    texts = [(f"{t.name}:\n" if t is not shown[0] else "") + (format_table(t.rows, cfg) if t.paper else format_rows(t.rows))
             for t in shown if t.terminal]
    return "\n\n".join(texts)


def proven_rates(cfg):
    """{norm column: the rate the paper proves for this study's case} (rates.PAPER_RATES through the
    verdict's lookup); empty when unknown."""
    if cfg is None:
        return {}
    found = {norm: verdict.expected(cfg, norm).rate for norm in names.ERROR_NORMS + names.REFERENCE_NORMS}
    return {norm: rate for norm, rate in found.items() if rate is not None}


def title(study, cfg=None):
    """A one-line plot title: the study type's, or the study name alone."""
    return studies.of(study.study_type).title(cfg, study.name) if cfg is not None else study.name


def format_rows(rows):
    """A right-aligned text table of any rows (the ε → 0 studies' tables), cells as in the rate table."""
    if not rows:
        return "(nothing solved)"
    return "\n".join(_aligned([("", [(c, [_format(c, row[c]) for row in rows]) for c in rows[0]])]))
