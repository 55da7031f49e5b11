"""Human-readable output: the terminal table, Markdown/LaTeX tables and the figures of a study of any type
(what its type says it reports)."""
import math
import re
import textwrap
from pathlib import Path

from .. import config, studies
from ..analysis import verdict
from ..analysis import rates
from ..analysis.rates import error_columns as norms  # the measured norms of a table, for report, plots, progress
from ..config import ConfigError, names
from ..record import csvfile
from . import captions, latex, pressure, verdicts
from . import plots as plotting  # its matplotlib import waits inside its functions

TERMINAL_WIDTH = 120  # columns of a terminal table; wider ones wrap into blocks
PAPER_LEADING = ("N", "h", "epsilon", "newton_its")  # what a paper shows before the errors
ALWAYS = ("L2", "H1", "L2_ref", "H1_ref")  # in the paper columns whether the paper bounds them or not
FORMATS = {"h": ".3e", "epsilon": ".3e", "time_s": ".2f"}
# gmsh/file meshes: their size spread and Γ_C, as in the CSV
FORMATS.update({"h_min": ".3e", "gamma_c_measure": ".6f", "gamma_c_quasi_uniformity": ".3f", "alpha": "g", "p": "g"})
CONSTANT = ("N", "levels", "converged", "newton_its", "points")  # one value on every row: said in the caption
PARAMETERS = ("alpha", "p")  # a study's parameters: 1, 1.5, not 1.000e+00
DETAILS = ("time_s", "dofs", "newton_its")  # how a solve went: in the .md and .csv, not in a table of results
NAMING = ("study", "solver")  # a sub-study's name and kind: α and p say both (a table of an α × p sweep)
SPACES = {"L2": "$L^2$", "H1": "$H^1$", "L2_gc": r"$L^2(\Gamma_C)$", "L2_gamma_c": r"$L^2(\Gamma_C)$",
          "pos_gc": r"$L^{\alpha+1}(\Gamma_C)$", "eps_max": r"$\varepsilon_{\max}$",
          "eps_min": r"$\varepsilon_{\min}$"}
RATE_DEFINITION = r"rate: $\log(e_k/e_{k-1})/\log(h_k/h_{k-1})$ between successive levels"


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
        if "epsilon" in lead and all(row["epsilon"] == 0 for row in rows):  # the Signorini problem: no ε,
            lead = [c for c in lead if c != "epsilon"] + [c for c in ("contact_measure",) if c in rows[0]]
        lead += [c for c in names.HERTZ if c in rows[0] and "half_width" in rows[0]]  # a Hertz scene's own figures
        return lead, paper_norms(measured, proven or {})  # its contact set's measure instead
    unknown = [c for c in columns if c not in rows[0]]
    if unknown:
        raise ConfigError("output.columns", f"{unknown[0]!r} is not a column of this study; it has "
                                            + ", ".join(c for c in rows[0] if not c.startswith("rate_")))
    return [c for c in columns if c not in measured], [c for c in columns if c in measured]


def paper_norms(measured, proven):
    """L2 and H1 (or their _ref forms), proven rate or not, and the measured norms with a proven rate,
    pos_gc_scaled left out beside pos_gc (a power of it, Corollary 3.2 ii); else the first two measured."""
    shown = {n for n in measured if n in proven and not (n.startswith("pos_gc_scaled")
                                                         and n.replace("_scaled", "") in proven)}
    return [n for n in measured if n in shown or n in ALWAYS] or measured[:2]


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
    order = list(rows[0])
    first = min((order.index(n) for n in shown if n in order), default=len(order))
    before = [c for c in lead if c not in order or order.index(c) < first]  # the level's identity, then the
    after = [c for c in lead if c not in before]  # errors, then timings and solver details (`all`)
    def columns_of(chosen_columns):
        return [(label(c), [_format(c, r.get(c)) for r in rows]) for c in chosen_columns]
    groups = [("", columns_of(before))]
    groups += [(label(n), [("error", [_format(n, r.get(n)) for r in rows]),
                                     ("rate", [_format("rate_", r.get(f"rate_{n}")) for r in rows])])
               for n in shown]
    return "\n".join(_aligned(groups + [("", columns_of(after))]) + _failures(rows, end=""))


def _aligned(groups, width=TERMINAL_WIDTH):
    """Lines of a right-aligned table whose column groups [(title, [(header, cells)])] get their title
    centred above them; wider than `width`, it is wrapped into blocks that repeat the first column."""
    units = [unit for title, columns in groups
             for unit in ([group for group in [(title, columns)]] if title else [("", [c]) for c in columns])]
    key = units[0]
    blocks = [[]]
    for unit in units:
        if blocks[-1] and max(map(len, _block(_merged(blocks[-1] + [unit])))) > width:
            blocks.append([key])
        blocks[-1].append(unit)
    return [line for k, block in enumerate(blocks) for line in ([""] if k else []) + _block(_merged(block))]


def _merged(units):
    """Neighbouring untitled single columns as one group again (two spaces apart, not four)."""
    groups = []
    for title, columns in units:
        if not title and groups and not groups[-1][0]:
            groups[-1] = ("", groups[-1][1] + columns)
        else:
            groups.append((title, columns))
    return groups


def _block(groups):
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


def comparison(studies, fit_levels=None):
    """One row per study ({label: rows}): levels, finest converged h, total wall time, per norm the
    finest error (<norm>_finest) and its rate (<norm>_fit), the slope fitted as the study's verdict fits it:
    over its last fit_levels[label] levels (a study not in `fit_levels`: rates.FIT_LEVELS)."""
    all_norms = list(dict.fromkeys(norm for rows in studies.values() for norm in norms(rows)))
    table = []
    for label, rows in studies.items():
        ok = [row for row in rows if row["converged"]]
        row = {"study": label, "levels": len(rows), "finest_h": ok[-1]["h"] if ok else None,
               "time_s": sum(row["time_s"] or 0.0 for row in rows)}
        for norm in all_norms:
            points = [(row["h"], row[norm]) for row in ok if row.get(norm)]
            row[f"{norm}_finest"] = points[-1][1] if points else None
            k = (fit_levels or {}).get(label, rates.FIT_LEVELS)
            row[f"{norm}_fit"] = rates.slope(*zip(*points), k=k) if points else None
        table.append(row)
    return table, all_norms


def fitted_over(studies, fit_levels=None):
    """'the last k levels' when every study is fitted over the same k, else each study's own."""
    ks = {(fit_levels or {}).get(label, rates.FIT_LEVELS) for label in studies}
    return f"the last {ks.pop()} levels" if len(ks) == 1 else "each study's last verification.fit_levels levels"


def summary_table(studies, fit_levels=None):
    """The comparison for the terminal: one line per study, each norm's finest error and fitted slope
    under its name (wrapped into blocks at TERMINAL_WIDTH)."""
    table, all_norms = comparison(studies, fit_levels)
    lead = [("study", [row["study"] for row in table]), ("levels", [str(row["levels"]) for row in table]),
            ("finest h", [_format("h", row["finest_h"]) for row in table]),
            ("time_s", [_format("time_s", row["time_s"]) for row in table])]
    groups = [("", lead)] + [(names.name(norm).text, [
        ("finest", [_format(norm, row[f"{norm}_finest"]) for row in table]),
        ("fit", [_rate(row[f"{norm}_fit"], "-") for row in table])]) for norm in all_norms]
    return "\n".join(_aligned(groups))


def write_comparison(studies, folder, fit_levels=None):
    """compare.csv, compare.md and compare.tex (fitting a page) of `studies` in `folder`; the paths."""
    table, all_norms = comparison(studies, fit_levels)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = [folder / f"compare.{ext}" for ext in ("csv", "md", "tex")]
    paths[0].write_text(csvfile.text(table))
    header = ["study", "levels", "finest h", "time [s]"] + [f"{names.name(n).text} {k}" for n in all_norms
                                                             for k in ("finest", "fit")]
    lines = ["| " + " | ".join(header) + " |", "|:---|" + "---:|" * (len(header) - 1)]
    lines += ["| " + " | ".join([_markdown_text(row["study"]), str(row["levels"]), _paper_number(row["finest_h"]),
                                f"{row['time_s']:.2f}"] + [cell for n in all_norms for cell in (
                                    _paper_number(row[f"{n}_finest"]), _rate(row[f"{n}_fit"], "–"))]) + " |"
              for row in table]
    paths[1].write_text("\n".join(lines) + "\n")
    paths[2].write_text(_comparison_tex(table, all_norms, fitted_over(studies, fit_levels)))
    return paths


def _paper_number(value, missing="–"):
    return missing if value is None else f"{value:.3e}"


def _comparison_tex(table, all_norms, fitted):
    """compare.tex: norms down, studies across (each its finest error and fitted slope), so that norms ×
    studies fit one table; levels, finest h and time in the first rows; split by studies past \\textwidth."""
    number = lambda v: "--" if v is None else latex.number(v, 3)  # noqa: E731
    lead = [("", ["levels", "finest $h$", "time [s]"] + [_header(n) for n in all_norms])]
    cells = []
    for row in table:
        cells += [("finest", [str(row["levels"]), number(row["finest_h"]), f"{row['time_s']:.2f}"]
                   + [number(row[f"{n}_finest"]) for n in all_norms]),
                  ("fit", ["", "", ""] + [_rate(row[f"{n}_fit"], "--", latex.rate) for n in all_norms])]
    caption = ("Comparison of " + ", ".join(label_tex(row["study"]) for row in table) + ": per norm the error on "
               "the finest converged level and the slope of $\\log e$ against $\\log h$ fitted over "
               f"{fitted}; time: wall time of all levels" + "".join(
                   f"; {d}" for d in map(_definition, all_norms) if d) + ".")
    text = latex.table(lead + cells, [(label_tex(row["study"]), 2) for row in table], caption,
                       latex.label("compare"), 3 + len(all_norms), align="l" + "r" * len(cells))
    return "% comparison table written by signorini compare; needs \\usepackage{booktabs}\n" + text


def label_tex(label):
    """A study's label in LaTeX: its text escaped, "α=1.5" or "p = 2" parts as mathematics."""
    text = _latex_text(label)
    return re.sub(r"\$\\(\w+)\$\s*=\s*([-+\d.eE]+)|\b([A-Za-z])\s*=\s*([-+\d.eE]+)",
                  lambda m: f"$\\{m[1]} = {m[2]}$" if m[1] else f"${m[3]} = {m[4]}$", text)


# --- tables for papers and notebooks (deal.II ConvergenceTable style: error, then its rate) ----

def markdown_table(rows, digits=3, columns="paper", proven=None):
    """The rate table as GitHub Markdown: errors in scientific notation with `digits`, rates .2f; each
    norm's two columns headed "<name> error", "<name> rate"."""
    lead, shown = choose(rows, columns, proven)
    header = [names.name(c).text for c in lead] + [f"{names.name(n).text} {k}" for n in shown
                                                   for k in ("error", "rate")]
    lines = ["| " + " | ".join(header) + " |", "|" + "---:|" * len(header)]
    for row in rows:
        cells = [_markdown_cell(c, row, digits) for c in lead]
        for norm in shown:
            cells += [_paper_cell(norm, row, digits, _scientific, "–"), _rate(row.get(f"rate_{norm}"), "–")]
        lines.append("| " + " | ".join(cells) + " |")
    notes = _failures(rows)
    return "\n".join(lines + ([""] + notes if notes else [])) + "\n"  # a blank line ends the table


def latex_table(rows, digits=3, caption="", columns="paper", proven=None, key=None, short=False):
    """The rate table as a booktabs `table` float (needs \\usepackage{booktabs}, said in its first line):
    "error | rate" under each norm's short name, numbers as $2.303\\times10^{-2}$, columns N or the
    caption already gives left out, a layout that fits \\textwidth (latex.table), a \\label `key`; `short`:
    norms headed by their space alone (a table whose errors are not u - u_h: the caption says what), the
    solver's details (time, DoFs, iterations) left to the Markdown table."""
    lead, shown = choose(rows, columns, proven)
    lead = [c for c in lead if not (c in NAMING and "alpha" in lead) and not (short and c in DETAILS)]
    lead, given = redundant(rows, lead)
    cells = [(_header(c, short), [_latex_cell(c, row, digits) for row in rows]) for c in lead]
    for norm in shown:
        cells += [("error", [_paper_cell(norm, row, digits, latex.number, "--") for row in rows]),
                  ("rate", [_rate(row.get(f"rate_{norm}"), "--", latex.rate) for row in rows])]
        if f"fit_{norm}" in lead:  # a fitted slope beside its error
            cells.append(("fit", [_latex_cell(f"fit_{norm}", row, digits) for row in rows]))
    groups = [(_header(n, short), 2 + (f"fit_{n}" in lead)) for n in shown]
    lead_cells = [cell for cell, c in zip(cells, lead) if not (c.startswith("fit_") and c[4:] in shown)]
    cells = lead_cells + cells[len(lead):]
    text = latex.table(cells, groups, _caption(caption, lead, shown, rows, given),
                       key or latex.label("rates"), len(rows))
    return "% rate table written by signorini; needs \\usepackage{booktabs}\n" + text


def redundant(rows, lead):
    """(lead without the columns the caption can state, those statements as LaTeX): h when N gives it
    (stated whenever N is shown), ε when it equals h or is one value on every level."""
    given, law = [], h_law(rows) if "N" in lead else None
    if law is not None:
        lead, given = [c for c in lead if c != "h"], [_h_statement(*law)]
    fixed = [c for c in lead if c in CONSTANT and len(rows) > 1 and len({str(row.get(c)) for row in rows}) == 1]
    lead, given = [c for c in lead if c not in fixed], given + [_fixed(c, rows[0][c]) for c in fixed]
    eps = [row.get("epsilon") for row in rows]
    if "epsilon" in lead and eps and all(isinstance(e, (int, float)) and e > 0 for e in eps):
        law = eps_law(eps, [row.get("h") for row in rows])
        if law is not None:
            lead, given = [c for c in lead if c != "epsilon"], given + [law]
    return lead, given


def _fixed(column, value):
    """A column one value on every row, said in the caption instead."""
    if isinstance(value, bool):
        return "every solve converged" if value else "no solve converged"
    return f"{_header(column)} = " + (f"${value}$" if isinstance(value, int) else latex.escape(value))


def eps_law(eps, h):
    """ε = c h^q (q = 0, 1, 1/2, 2, 3) on every level as LaTeX, else None."""
    for q, power in ((0, ""), (1, "h"), (0.5, r"\sqrt{h}"), (2, "h^{2}"), (3, "h^{3}")):
        if q and not all(isinstance(x, (int, float)) and x > 0 for x in h):
            continue
        c = [e / (x ** q if q else 1.0) for e, x in zip(eps, h)]
        if max(c) - min(c) <= 1e-9 * max(c):
            factor = "" if power and math.isclose(c[0], 1.0, rel_tol=1e-9) else latex.constant(float(f"{c[0]:.6g}"))
            return rf"$\varepsilon = {factor}{power}$"
    return None


def h_law(rows):
    """(c, k) when h = c N^{-1/k} on every level (k = 1: N cells per side; k = d: N cells of a uniformly
    refined mesh), else None."""
    if len(rows) < 2 or not all(row.get("h") and row.get("N") for row in rows):
        return None
    for k in (1, 2, 3):
        products = [row["h"] * row["N"] ** (1 / k) for row in rows]
        if max(products) - min(products) <= 1e-9 * products[0]:
            return products[0], k
    return None


def _h_statement(c, k):
    """h = c/N with N cells per side, or h = c N^{-1/k} with N cells: c as √m when it is one."""
    root = round(c * c)
    value = (rf"\sqrt{{{root}}}" if math.isclose(c * c, root, rel_tol=1e-9) and not c.is_integer()
             else latex.constant(float(f"{c:.4g}")))
    if k == 1:
        return rf"$N$: cells per side, $h = {value}/N$ the largest cell diameter"
    return rf"$N$: the number of cells, $h = {value}\,N^{{-1/{k}}}$ the largest cell diameter"


def _known(column):
    """Whether names.py names the column (its LaTeX is ours); any other name came from a file."""
    return column in names.NORMS or column in names.COLUMNS or (column.endswith("_ref") and column[:-4] in names.NORMS)


def _header(column, short=False):
    """A column's LaTeX header: a norm written out (its space alone if `short`), a known column's symbol, a
    fitted slope as "fit" and its norm, else its own name as words."""
    if column.startswith("fit_"):
        return "fit " + _header(column[4:], True)
    if short and column in SPACES:
        return SPACES[column]
    return names.name(column).tex if _known(column) else _latex_text(column.replace("_", " "))


def _markdown_cell(column, row, digits):
    """A Markdown cell: α and p as %g, fitted slopes .2f, the rest as _paper_cell."""
    value = row.get(column)
    if isinstance(value, float) and (column in PARAMETERS or column.startswith("fit_")):
        return f"{value:g}" if column in PARAMETERS else f"{value:.2f}"
    return _paper_cell(column, row, digits, _scientific, "–", _markdown_text)


def _latex_cell(column, row, digits):
    """A LaTeX cell: α and p as the numbers they are, fitted slopes as rates, the rest as _paper_cell."""
    value = row.get(column)
    if column in PARAMETERS and isinstance(value, float):
        return f"${latex.constant(value)}$"
    if column.startswith("fit_") and isinstance(value, float):
        return latex.rate(value)
    return _paper_cell(column, row, digits, latex.number, "--", _latex_text)


def _definition(column):
    """What a header leaves to the caption: a short name's meaning (a norm written out in its header: None)."""
    known = names.name(column)
    if not _known(column) or not known.definition:
        return None
    norm = column in names.NORMS or column[:-4] in names.NORMS  # a norm's definition is a sentence
    return known.definition if norm else f"{known.tex}: {known.definition}"


def _caption(caption, lead, shown, rows, given=()):
    """The caption: the study (LaTeX, see caption_of), what the table leaves out, what each short name
    means, the rate, and the failed levels."""
    n_given = any(g.startswith("$N$:") for g in given)  # with the law of h
    defined = [d for c in lead + shown if not (c == "N" and n_given) for d in [_definition(c)] if d]
    given = [g for g in given if not (g.startswith(r"$\varepsilon =") and r"$\varepsilon =" in caption)]
    text = (caption + ". " if caption else "") + "; ".join(
        list(given) + defined + ([RATE_DEFINITION] if shown else [])) + "."
    return " ".join([text] + [latex.escape(line) for line in _failures(rows)])


def caption_of(name, cfg=None, variational=False, slug=False):
    """The study in a caption, from its config's fields: d, α, ε as a formula (or the Signorini variational
    inequality), the exact solution (or the data) typeset, Γ_C; the study's name only when `slug` (or without
    a config); LaTeX with every user-given text escaped."""
    text = f"Study {latex.escape(name)}" if slug or cfg is None else "Errors and observed rates"
    if cfg is None:
        return text
    parts = [f"$d = {cfg.dimension}$"]
    if variational:
        parts.append(r"the Signorini variational inequality ($\varepsilon = 0$)")
    else:
        law = config.LAWS[cfg.epsilon.law]
        theta = "" if cfg.epsilon.theta == 1 and law.p != 0 else latex.constant(cfg.epsilon.theta)  # 1 h: h
        law = law.tex.format(p=cfg.epsilon.p).strip()
        parts += [rf"$\alpha = {latex.constant(cfg.alpha)}$", rf"$\varepsilon = {theta}{law}$"]
    parts += [part for part in [_problem(cfg.problem)] if part]
    parts.append(r"contact boundary $\Gamma_C$: " + latex.escape(cfg.contact))
    if cfg.mesh.kind == "gmsh":
        parts.append(r"gmsh geometry \texttt{" + latex.escape(Path(cfg.mesh.geometry).stem) + "}")
    return f"{text}: " + ", ".join(parts)


def _typeset(expression):
    """An expression of the config (or a vector of them: elasticity's components) as LaTeX."""
    if isinstance(expression, tuple):
        return r"\left(" + ", ".join(latex.expression(e.tree) for e in expression) + r"\right)"
    return latex.expression(expression.tree)


def _problem(problem):
    """$u = ...$ (manufactured), or the data $f = ...$ (and $g$); a formula too long for a caption named."""
    given = [("u", problem.exact)] if problem.exact is not None else [("f", problem.f), ("g", problem.g)]
    typeset = [(symbol, _typeset(e)) for symbol, e in given if e is not None]
    if any(len(tex) > 160 for _, tex in typeset):  # unbreakable in a caption line
        return "the solution or data as written in the study's config"
    if not typeset:  # no load and no Γ_C data (a Hertz contact: the gap alone)
        return None
    words = "exact solution" if problem.exact is not None else "data"
    return words + " " + ", ".join(f"${symbol} = {tex}$" for symbol, tex in typeset)


def _paper_cell(column, row, digits, scientific, missing, text=str):
    value = row.get(column)
    if column == "newton_its" and not row["converged"]:
        return f"{value} (failed)"
    if value is None:
        return missing
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, str):
        return text(value)
    return scientific(value, digits) if isinstance(value, float) else str(value)


def _rate(value, missing, form="{:.2f}".format):
    return missing if value is None else form(value)


def _scientific(value, digits):
    return f"{value:.{digits}e}"


def _markdown_text(value):
    """A text cell in a Markdown table: a | would end the cell."""
    return value.replace("|", "\\|")


def _latex_text(value):
    """A text cell in LaTeX, escaped, cut at latex.MAX_TEXT characters (a table column, not a page)."""
    return latex.escape(value if len(value) <= latex.MAX_TEXT else value[:latex.MAX_TEXT - 3] + "...")


def _failures(rows, end="."):
    """One line per row that did not converge: its level (a sweep's: its N, α and ε)."""
    return [f"{_which(row)} did not converge: {row.get('reason')}{end}"
            for row in rows if row.get("converged") is False]


def _which(row):
    if "level" in row:
        return f"Level {row['level']} (N = {row['N']})"
    return "Solve " + ", ".join(f"{names.name(k).text} = {row[k]:g}" for k in ("N", "alpha", "epsilon") if k in row)


# --- everything a study leaves besides rates.csv and study.h5 -----------------------------------

def write(study, cfg=None, digits=3, plots=True, folder=None, columns=None, figure=None, suffix="", summary=None):
    """The tables (<name><suffix>.md, .tex) and (if `plots`) the figures a study of its type reports, into
    `folder`; the paths written. `columns` as output.columns for its rate tables (default: the config's,
    else "paper"); given, they also choose the plotted norms. `figure`: plots.Layout options; `summary`
    (verdict.Summary): its verdicts under the first Markdown table and as verdict<suffix>.tex."""
    folder = Path(folder or study.folder)
    shown, figures = studies.of(study.study_type).reported(cfg, study.tables or {"rates": study.rows})
    description = f"Study {study.name}" + (f": {cfg.description}" if cfg is not None and cfg.description else "")
    chosen, proven = _columns_of(cfg, columns), proven_rates(cfg)
    written = []
    for table in shown:
        path = folder / f"{table.name}{suffix}"
        path.parent.mkdir(parents=True, exist_ok=True)
        how = (chosen, proven) if table.paper else ("all", {})
        part = "" if table.paper and "/" not in table.name else f", table {table.name}"
        under = [] if summary is None or table is not shown[0] else verdicts.markdown_lines(summary)
        comment = (description + part).replace("--", "- -")  # "-->" in a description would end the comment
        written.append(path.with_name(path.name + ".md"))
        written[-1].write_text("\n".join([f"<!-- {comment} -->\n" + markdown_table(table.rows, digits, *how)
                                          .rstrip("\n")] + under) + "\n")
        key = latex.label(study.name, table.name if part else "", suffix)
        written.append(path.with_name(path.name + ".tex"))
        rows, shown_how = _on_a_page(table, how)
        written[-1].write_text(latex_table(rows, digits, _table_caption(study, cfg, table), *shown_how, key=key,
                                           short=not table.paper))
    if summary is not None and summary.norms:
        written.append(folder / f"verdict{suffix}.tex")
        written[-1].write_text(verdicts.latex_table(summary, latex.label(study.name, "verdict", suffix)))
    if plots:
        shown_norms = choose(study.rows, chosen, proven)[1] if chosen != "paper" and study.rows else None
        written += draw(figures, study, cfg, folder, proven, figure, shown_norms, suffix)
    return written


def _on_a_page(table, how):
    """(rows, (columns, proven)) of a table's LaTeX: an ε-sweep's on its finest mesh in L2 and H1 (every mesh
    and norm, hundreds of rows: its .md and .csv), any other table whole."""
    if table.name != "sweep" or not table.rows:
        return table.rows, how
    finest = max(row["N"] for row in table.rows)
    rows = [row for row in table.rows if row["N"] == finest]
    return rows, ([c for c in ("N", "alpha", "epsilon", "L2", "H1") if c in rows[0]], how[1])


def _table_caption(study, cfg, table):
    """A rate table's caption from its (sub-)study's config; another table's from what its rows are."""
    if not table.paper:
        return captions.of_table(table.name.split("/")[-1], cfg)
    parted = "/" in table.name and cfg is not None  # a sub-study's table (total_error): its own α and ε
    sub = dict(studies.of(study.study_type).sub_studies(cfg)) if parted else {}
    return caption_of(study.name, sub.get(table.name.split("/")[0], cfg), _variational(table.rows))


def _variational(rows):
    """Whether a table's levels solve the Signorini variational inequality (ε = 0 on every level)."""
    return bool(rows) and all(row.get("epsilon") == 0 for row in rows)


def draw(figures, study, cfg, folder, proven, figure=None, shown=None, suffix=""):
    """The study type's figures, each by its kind (convergence figures of the norms `shown`, all if None,
    their names ending in `suffix`); the paths written."""
    fit_levels = cfg.verification.fit_levels if cfg is not None else rates.FIT_LEVELS
    figure = dict({"width": cfg.output.figure_width or None} if cfg is not None else {}, **(figure or {}))
    written = []
    for fig in figures:
        if fig.kind == "convergence" and fig.data:
            written += plotting.write_all(fig.data, (folder / fig.name).parent, proven=proven,
                                          title=title(study, cfg), fit_levels=fit_levels, shown=shown,
                                          suffix=suffix, **figure)
        elif fig.kind == "model_error":
            written += [plotting.model_error(fig.data, folder / f"{fig.name}{suffix}", figure.get("width")
                                             or plotting.WIDTH_PT, figure.get("font", "cm"))
                        for suffix in (".png", ".pdf")]
        elif fig.kind == "comparison":
            written += plotting.write_comparison(fig.data, folder, figure.get("width"), figure.get("font", "cm"))
        elif fig.kind == "pressure":
            written += pressure.write(fig.data, folder / Path(fig.name).parent, figure.get("width"))
    return written


def terminal(study, cfg=None):
    """What a run or `report` prints of a study: its rate tables as format_table, its other tables whole."""
    shown, _ = studies.of(study.study_type).reported(cfg, study.tables or {"rates": study.rows})
    texts = [(f"{t.name}:\n" if t is not shown[0] else "")
             + (format_table(t.rows, cfg) if t.paper else format_rows(t.rows)) for t in shown if t.terminal]
    return "\n\n".join(texts)


def wrote(names, folder=None):
    """A command's closing line, 'wrote [into FOLDER:] a, b, ...', wrapped to TERMINAL_WIDTH between names; the
    files of a sub-folder (a total-error study's sub-studies) counted under the folder's name."""
    names = [str(name) for name in names]
    subs = list(dict.fromkeys(name.split("/")[0] for name in names if "/" in name))
    counts = {sub: sum(name.startswith(sub + "/") for name in names) for sub in subs}
    listed = [name for name in names if "/" not in name] + [f"{sub}/ ({counts[sub]} files)" for sub in subs]
    head = f"wrote into {folder}: " if folder is not None else "wrote "
    return textwrap.fill(head + ", ".join(listed), TERMINAL_WIDTH, subsequent_indent="  ",
                         break_long_words=False, break_on_hyphens=False)


def proven_rates(cfg):
    """{norm column: the rate the paper proves for this study's case} (rates.PAPER_RATES through the
    verdict's lookup); empty when unknown."""
    if cfg is None:
        return {}
    found = {norm: verdict.expected(cfg, norm).rate for norm in names.ERROR_NORMS + names.REFERENCE_NORMS}
    return {norm: rate for norm, rate in found.items() if rate is not None}


def title(study, cfg=None, slug=False):
    """A one-line plot title: the study type's without the study's name unless `slug` (no config: the name
    only when `slug`)."""
    if cfg is None:
        return study.name if slug else ""
    text = studies.of(study.study_type).title(cfg, study.name)
    return text if slug else text.removeprefix(f"{study.name}: ")


def format_rows(rows):
    """A right-aligned text table of any rows (the ε → 0 studies' tables), cells as in the rate table."""
    if not rows:
        return "(nothing solved)"
    return "\n".join(_aligned([("", [(c, [_format(c, row[c]) for row in rows]) for c in rows[0]])]))
