"""Human-readable output: the terminal table, Markdown/LaTeX rate tables, and a study read back from disk."""
import csv
import logging
import math
from dataclasses import dataclass, field
from pathlib import Path

from .. import config
from ..analysis import verdict
from ..analysis.rates import fitted
from ..analysis.rates import error_columns as norms  # the measured norms of a table, for report, plots, progress
from ..config import ConfigError, names
from ..record import results
from . import plots as plotting  # its matplotlib import waits inside its functions

COLUMN_SETS = ("paper", "all")  # output.columns / report --columns, besides a list of columns
PAPER_LEADING = ("N", "h", "epsilon", "newton_its")  # what a paper shows before the errors
ALWAYS = ("L2", "H1", "L2_ref", "H1_ref")  # in the paper columns whether the paper bounds them or not
TERMINAL_WIDTH = 120
FORMATS = {"h": ".3e", "epsilon": ".3e", "time_s": ".2f"}
# gmsh/file meshes: their size spread and Γ_C, as in the CSV
FORMATS.update({"h_min": ".3e", "gamma_c_measure": ".6f", "gamma_c_quasi_uniformity": ".3f", "alpha": "g", "p": "g"})
SPEC_ORDER = ("level", "N", "h", "dofs", "epsilon", "converged", "newton_its",
              "L2", "rate_L2", "H1", "rate_H1", "time_s")
FIT_LEVELS = 3  # fitted slopes without a config: verification.fit_levels' default
logger = logging.getLogger(__name__)
RATE_DEFINITION = r"rate: $\log(e_k/e_{k-1})/\log(h_k/h_{k-1})$ between successive levels"


@dataclass(frozen=True)
class Study:
    """A study read back from its folder: the table rows, its name and the resolved config text."""
    name: str
    folder: Path
    rows: list
    config_text: str = ""  # empty when read from rates.csv alone
    attrs: dict = field(default_factory=dict, repr=False)


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
    """L2 and H1 (or their _ref forms), proven rate or not, and the measured norms with a proven rate,
    pos_gc_scaled left out beside pos_gc (a power of it, Corollary 3.2 ii); else the first two measured."""
    shown = {n for n in measured if n in proven and not (n == "pos_gc_scaled" and "pos_gc" in proven)}
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
    return [f"Level {row['level']} (N = {row['N']}) did not converge: {row['reason']}{end}"
            for row in rows if not row["converged"]]


# --- reading a finished or partial study back ---------------------------------------------------

class DamagedResults(OSError):
    """A study file that cannot be read as a table (cut short, NaN where a count belongs, a group
    missing): bad input for report and compare, which name the file."""


def load(path):
    """Read a study from its folder, its study.h5 or its rates.csv (no recomputation). A damaged
    study.h5 gives way to an intact rates.csv beside it (a warning says so)."""
    path = Path(path)
    if path.is_dir():
        h5, csv_path = path / "study.h5", path / "rates.csv"
        if not h5.exists() and not csv_path.exists():
            raise FileNotFoundError("neither study.h5 nor rates.csv in this folder (not a study folder)")
        path = h5 if h5.exists() else csv_path
    if not path.exists():
        raise FileNotFoundError("No such file or folder")
    if path.suffix == ".csv":
        return _load_csv(path)
    try:
        return _load_h5(path)
    except DamagedResults as err:
        fallback = path.parent / "rates.csv"
        if not fallback.exists():
            raise
        try:
            study = _load_csv(fallback)
        except DamagedResults as also:
            raise DamagedResults(f"{err}; {also}") from None
        logger.warning("%s; reading %s instead", err, fallback)
        return study


def _load_h5(path):
    import h5py
    try:
        with h5py.File(path, "r") as h5:
            attrs = {key: _python(value) for key, value in h5.attrs.items()}
            if attrs.get("study_type") in ("epsilon_sweep", "total_error"):  # docs/limit.md: no rate table
                raise ConfigError("study_type", f"an {attrs['study_type']} study has no rate table to report; "
                                                "its tables are the CSV files next to study.h5 (README: Results)")
            rows = _h5_rows(h5, path)
    except DamagedResults:
        raise
    except (OSError, KeyError, ValueError) as err:  # h5py: truncated, or not HDF5 at all
        raise DamagedResults(f"{path}: damaged, not readable as HDF5 ({_first_line(err)})") from None
    _check_rows(rows, path)
    text = attrs.get("config_resolved") or attrs.get("config", "")
    return Study(attrs.get("study", path.parent.name), path.parent, rows, text, attrs)


def _h5_rows(h5, path):
    table = h5.get("table")
    if table is None:
        raise DamagedResults(f"{path}: damaged, no table group")
    columns = _columns(table)
    groups = sorted(name for name in h5 if name.startswith("level_"))
    return [{c: _python(h5[name].attrs.get(c)) for c in columns} for name in groups]


def _columns(table):
    if "columns" in table.attrs:
        return [str(c) for c in table.attrs["columns"]]
    names = list(table)  # written before the `columns` attribute: SPEC order first, then by name
    return [c for c in SPEC_ORDER if c in names] + [c for c in names if c not in SPEC_ORDER]


def _python(value):
    """numpy scalars from h5py as Python values (bool, int, float, str)."""
    if value is None:
        return None
    if isinstance(value, bytes):
        return value.decode()
    return value.item() if hasattr(value, "item") and getattr(value, "ndim", 1) == 0 else value


def _load_csv(path):
    try:
        with open(path, newline="") as f:
            reader = csv.DictReader(f)
            raw = list(reader)
    except (UnicodeDecodeError, csv.Error) as err:
        raise DamagedResults(f"{path}: damaged, not a CSV table ({_first_line(err)})") from None
    for k, row in enumerate(raw):
        if None in row or None in row.values():  # more or fewer fields than the header: cut short
            raise DamagedResults(f"{path}: damaged, row {k + 1} does not have the header's "
                                 f"{len(reader.fieldnames)} fields")
    rows = [{key: _csv_value(value) for key, value in row.items()} for row in raw]
    _check_rows(rows, path)
    return Study(path.parent.name, path.parent, rows)


# what every row of a study's table holds, whatever else it has
ROW_TYPES = {"level": int, "N": int, "dofs": int, "h": float, "converged": bool}


def _check_rows(rows, path):
    """Raise DamagedResults naming `path` unless every row has its level's counts and a finite h > 0."""
    for row in rows:
        for column, kind in ROW_TYPES.items():
            if not _valid(row.get(column), kind):
                raise DamagedResults(f"{path}: damaged, {column} = {row.get(column)!r} "
                                     f"at level {row.get('level')!r}")


def _valid(value, kind):
    if kind is bool or isinstance(value, bool):
        return isinstance(value, bool) and kind is bool
    if not isinstance(value, (int, float)) or not math.isfinite(value):
        return False
    return float(value).is_integer() and value >= 0 if kind is int else value > 0


def _first_line(err):
    return str(err).splitlines()[0] if str(err) else type(err).__name__


def _csv_value(text):
    if text == "":
        return None
    if text in ("true", "false"):
        return text == "true"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


# --- everything a study leaves besides rates.csv and study.h5 -----------------------------------

def write(study, cfg=None, digits=3, plots=True, folder=None, columns=None, figure=None, summary=None):
    """rates.md, rates.tex and (if `plots`) the figures of `study` into `folder`; the paths written.
    `columns` as output.columns (default: the config's, else "paper"); `figure`: plots.Layout options;
    `summary` (verdict.Summary): its verdicts under the tables."""
    folder = Path(folder or study.folder)
    folder.mkdir(parents=True, exist_ok=True)
    caption = f"Study {study.name}" + (f": {cfg.description}" if cfg is not None and cfg.description else "")
    chosen, proven = _columns_of(cfg, columns), proven_rates(cfg)
    written = [folder / "rates.md", folder / "rates.tex"]
    verdicts = ([], []) if summary is None else (verdict.markdown_lines(summary), verdict.latex_lines(summary))
    written[0].write_text("\n".join([f"<!-- {caption} -->\n" + markdown_table(study.rows, digits, chosen, proven)
                                     .rstrip("\n")] + verdicts[0]) + "\n")
    written[1].write_text("\n".join([latex_table(study.rows, digits, caption, chosen, proven).rstrip("\n")]
                                    + verdicts[1]) + "\n")
    if plots and study.rows:
        fit_levels = cfg.verification.fit_levels if cfg is not None else FIT_LEVELS
        figure = dict({"width": cfg.output.figure_width or None} if cfg is not None else {}, **(figure or {}))
        written += plotting.write_all(study.rows, folder, proven=proven, title=title(study, cfg),
                                      fit_levels=fit_levels, **figure)
    return written


def proven_rates(cfg):
    """{norm column: the rate the paper proves for this study's case} (rates.PAPER_RATES through the
    verdict's lookup); empty when unknown."""
    if cfg is None:
        return {}
    found = {norm: verdict.expected(cfg, norm).rate for norm in names.ERROR_NORMS + names.REFERENCE_NORMS}
    return {norm: rate for norm, rate in found.items() if rate is not None}


def title(study, cfg=None):
    """A one-line plot title: dimension, alpha and the eps law, or the study name alone."""
    if cfg is None:
        return study.name
    if cfg.study_type == "signorini":  # the variational inequality: no alpha, no eps (docs/limit.md)
        return f"{study.name}: d = {cfg.dimension}, Signorini variational inequality (ε = 0)"
    law = "θ" + config.LAWS[cfg.epsilon.law].text.format(p=cfg.epsilon.p)
    return f"{study.name}: d = {cfg.dimension}, α = {cfg.alpha:g}, ε = {law}, θ = {cfg.epsilon.theta:g}"


# --- the ε → 0 studies (docs/limit.md): their tables in the terminal, sub-study reports, the figure ----

def write_limit(cfg, result, named):
    """What an ε-sweep or total-error study leaves besides its tables: each total-error sub-study's
    rates.md/.tex (and plots), the sweep's model-error figure (plots only with output.plots); the paths."""
    written = []
    if cfg.study_type == "total_error":
        for sub, levels in result.studies.values():
            if levels:
                study = Study(sub.study, sub.output_dir, results.table(levels))
                written += write(study, sub, sub.output.digits, plots=sub.output.plots)
    elif cfg.output.plots and named.get("sweep"):
        finest = max(row["N"] for row in named["sweep"])
        rows = [row for row in named["sweep"] if row["N"] == finest]
        written += [plotting.model_error(rows, cfg.output_dir / f"model_error{suffix}") for suffix in (".png", ".pdf")]
    return written


def limit_summary(cfg, named, written):
    """The terminal text of an ε-sweep or total-error study: its reference, fitted or total table."""
    lines = [f"study {cfg.study} ({cfg.study_type}): {cfg.output_dir}"]
    for name in ("reference", "fitted", "total"):
        if name in named:
            lines.append(f"\n{name}:\n{format_rows(named[name])}")
    files = [f"{name}.csv" for name in named] + [str(path.relative_to(cfg.output_dir)) for path in written]
    lines.append("wrote " + (", ".join(files) if len(files) <= 4 else f"{len(files)} tables and figures "
                             "(rates.md, rates.tex, plots) in the sub-study folders"))
    return "\n".join(lines)


def format_rows(rows):
    """A right-aligned text table of any rows (the ε → 0 studies' tables), cells as in the rate table."""
    if not rows:
        return "(nothing solved)"
    return "\n".join(_aligned([("", [(c, [_format(c, row[c]) for row in rows]) for c in rows[0]])]))
