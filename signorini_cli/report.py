"""Human-readable output: the terminal table, Markdown/LaTeX rate tables, and a study read back from disk."""
import csv
from dataclasses import dataclass, field
from pathlib import Path

from . import results
from .rates import error_columns as norms  # the measured norms of a table, for report, plots, progress

FORMATS = {"h": ".4e", "epsilon": ".3e", "time_s": ".2f"}
SHOWN = ("level", "N", "h", "dofs", "epsilon", "converged", "newton_its")
# gmsh/file meshes: their size spread and Γ_C, as in the CSV
MESH_FORMATS = {"h_min": ".4e", "gamma_c_measure": ".6f", "gamma_c_quasi_uniformity": ".3f"}
FORMATS.update(MESH_FORMATS)
SHOWN += tuple(MESH_FORMATS)
SPEC_ORDER = ("level", "N", "h", "dofs", "epsilon", "converged", "newton_its",
              "L2", "rate_L2", "H1", "rate_H1", "time_s")
# norm column -> (Markdown, LaTeX math) label; a column missing here is shown by its name
LABELS = {
    "L2": ("‖u − u_h‖_L²(Ω)", r"\|u-u_h\|_{L^2(\Omega)}"),
    "H1": (r"\|u − u_h\|_H¹(Ω)", r"|u-u_h|_{H^1(\Omega)}"),
    # the contact-boundary terms of Lemma 3.1 and Corollary 3.2 (issue 4's column names)
    "L2_gc": ("‖u − u_h‖_L²(Γ_C)", r"\|u-u_h\|_{L^2(\Gamma_C)}"),
    "pos_gc": ("‖[u]₊ − [u_h]₊‖_L^(α+1)(Γ_C)", r"\|[u]_+-[u_h]_+\|_{L^{\alpha+1}(\Gamma_C)}"),
    "pos_gc_scaled": ("‖[u]₊ − [u_h]₊‖^((α+1)/2)", r"\|[u]_+-[u_h]_+\|_{L^{\alpha+1}(\Gamma_C)}^{(\alpha+1)/2}"),
    "energy_err": ("energy error (Lemma 3.1)",
                   r"(|u-u_h|_{H^1}^2+\varepsilon^{-1}\|[u]_+-[u_h]_+\|_{L^{\alpha+1}(\Gamma_C)}^{\alpha+1})^{1/2}"),
}
# the columns before the errors in the paper tables: (column, Markdown header, LaTeX header)
PAPER_COLUMNS = (("N", "N", "$N$"), ("h", "h", "$h$"), ("dofs", "DoFs", "DoFs"),
                 ("epsilon", "ε", r"$\varepsilon$"), ("newton_its", "Newton", "Newton"))
FIT_LEVELS = 3  # fitted slopes use the last 3 converged levels (least squares in log-log)


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
    from . import rates
    return rates.fitted(list(h), list(e), [True] * len(e), k)


def format_table(rows):
    """The rate table, right-aligned: errors .3e, rates .2f, '-' where a rate is undefined."""
    if not rows:
        return "(no levels)"
    columns = [c for c in rows[0] if c in SHOWN or _is_error(c, rows[0]) or c.startswith("rate_")]
    columns.append("time_s")
    cells = [[_format(column, row.get(column)) for column in columns] for row in rows]
    widths = [max(len(column), *(len(line[i]) for line in cells)) for i, column in enumerate(columns)]
    lines = ["  ".join(column.rjust(w) for column, w in zip(columns, widths))]
    lines += ["  ".join(cell.rjust(w) for cell, w in zip(line, widths)) for line in cells]
    failed = [row for row in rows if not row["converged"]]
    lines += [f"level {row['level']} (N={row['N']}) did not converge: {row['reason']}" for row in failed]
    return "\n".join(lines)


def _is_error(column, row):
    return f"rate_{column}" in row


def _format(column, value):
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "NO"
    if column.startswith("rate_"):
        return f"{value:.2f}"
    if column in FORMATS:
        return f"{value:{FORMATS[column]}}"
    if isinstance(value, float):
        return f"{value:.3e}"
    return str(value)


def summary_table(studies):
    """One line per study ({label: rows}): levels, finest h, per norm the finest error and the slope
    fitted over the last levels, total wall time."""
    all_norms = list(dict.fromkeys(norm for rows in studies.values() for norm in norms(rows)))
    header = ["study", "levels", "finest h"] + [f"{n} ({k})" for n in all_norms for k in ("finest", "fit")]
    lines = [header + ["time_s"]]
    for label, rows in studies.items():
        ok = [row for row in rows if row["converged"]]
        line = [label, str(len(rows)), f"{ok[-1]['h']:.3e}" if ok else "-"]
        for norm in all_norms:
            points = [(row["h"], row[norm]) for row in ok if row.get(norm)]
            slope = fitted_slope(*zip(*points)) if len(points) > 1 else None
            line += [f"{points[-1][1]:.3e}" if points else "-", f"{slope:.2f}" if slope is not None else "-"]
        lines.append(line + [f"{sum(row['time_s'] or 0.0 for row in rows):.2f}"])
    widths = [max(len(line[i]) for line in lines) for i in range(len(header) + 1)]
    return "\n".join("  ".join(cell.ljust(w) if i == 0 else cell.rjust(w)
                               for i, (cell, w) in enumerate(zip(line, widths))) for line in lines)


# --- tables for papers and notebooks (deal.II ConvergenceTable style: error, then its rate) ----

def markdown_table(rows, digits=3):
    """The rate table as GitHub Markdown: errors in scientific notation with `digits`, rates .2f."""
    header = [md for _, md, _ in PAPER_COLUMNS]
    for norm in norms(rows):
        header += [LABELS.get(norm, (norm,))[0], "rate"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---:|" * len(header)]
    for row in rows:
        cells = [_paper_cell(column, row, digits, _scientific) for column, _, _ in PAPER_COLUMNS]
        for norm in norms(rows):
            cells += [_paper_cell(norm, row, digits, _scientific), _rate(row[f"rate_{norm}"], "–")]
        lines.append("| " + " | ".join(cells) + " |")
    notes = _failures(rows)
    return "\n".join(lines + ([""] + notes if notes else [])) + "\n"  # a blank line ends the table


def latex_table(rows, digits=3, caption=""):
    """The rate table as a booktabs tabular (needs \\usepackage{booktabs}); numbers as $m \\cdot 10^{k}$."""
    header = [tex for _, _, tex in PAPER_COLUMNS]
    for norm in norms(rows):
        header += [_latex_label(norm), "rate"]
    lines = [f"% {caption}" if caption else "% signorini rate table",
             r"\begin{tabular}{" + "r" * len(header) + "}", r"\toprule",
             " & ".join(header) + r" \\", r"\midrule"]
    for row in rows:
        cells = [_paper_cell(column, row, digits, _latex_number) for column, _, _ in PAPER_COLUMNS]
        for norm in norms(rows):
            cells += [_paper_cell(norm, row, digits, _latex_number), _rate(row[f"rate_{norm}"], "--")]
        lines.append(" & ".join(cells) + r" \\")
    lines += [r"\bottomrule", r"\end{tabular}"]
    lines += [f"% {line}" for line in _failures(rows)]
    return "\n".join(lines) + "\n"


def _paper_cell(column, row, digits, scientific):
    value = row.get(column)
    if column == "newton_its" and not row["converged"]:
        return f"{value} (failed)"
    if value is None:
        return "--" if scientific is _latex_number else "–"
    return scientific(value, digits) if isinstance(value, float) else str(value)


def _rate(value, missing):
    return missing if value is None else f"{value:.2f}"


def _scientific(value, digits):
    return f"{value:.{digits}e}"


def _latex_number(value, digits):
    mantissa, exponent = f"{value:.{digits}e}".split("e")
    return f"${mantissa} \\cdot 10^{{{int(exponent)}}}$"


def _latex_label(norm):
    if norm in LABELS:
        return f"${LABELS[norm][1]}$"
    return r"\texttt{" + norm.replace("_", r"\_") + "}"


def _failures(rows):
    return [f"Level {row['level']} (N = {row['N']}) did not converge: {row['reason']}."
            for row in rows if not row["converged"]]


# --- reading a finished or partial study back ---------------------------------------------------

def load(path):
    """Read a study from its folder, its study.h5 or its rates.csv (no recomputation)."""
    path = Path(path)
    if path.is_dir():
        h5, csv_path = path / "study.h5", path / "rates.csv"
        if not h5.exists() and not csv_path.exists():
            raise FileNotFoundError("neither study.h5 nor rates.csv in this folder (not a study folder)")
        path = h5 if h5.exists() else csv_path
    if not path.exists():
        raise FileNotFoundError("No such file or folder")
    return _load_csv(path) if path.suffix == ".csv" else _load_h5(path)


def _load_h5(path):
    import h5py
    with h5py.File(path, "r") as h5:
        attrs = {key: _python(value) for key, value in h5.attrs.items()}
        if attrs.get("study_type") in ("epsilon_sweep", "total_error"):  # docs/limit.md: no rate table
            from .config import ConfigError
            raise ConfigError("study_type", f"an {attrs['study_type']} study has no rate table to report; "
                                            "its tables are the CSV files next to study.h5 (README: Results)")
        table = h5.get("table")
        columns = _columns(table) if table is not None else []
        groups = sorted(name for name in h5 if name.startswith("level_"))
        rows = [{c: _python(h5[name].attrs.get(c)) for c in columns} for name in groups]
    text = attrs.get("config_resolved") or attrs.get("config", "")
    return Study(attrs.get("study", path.parent.name), path.parent, rows, text, attrs)


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
    with open(path, newline="") as f:
        rows = [{key: _csv_value(value) for key, value in row.items()} for row in csv.DictReader(f)]
    return Study(path.parent.name, path.parent, rows)


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

def write(study, cfg=None, digits=3, plots=True, folder=None):
    """rates.md, rates.tex and (if `plots`) the figures of `study` into `folder`; the paths written."""
    folder = Path(folder or study.folder)
    folder.mkdir(parents=True, exist_ok=True)
    caption = f"study {study.name}" + (f": {cfg.description}" if cfg is not None and cfg.description else "")
    written = [folder / "rates.md", folder / "rates.tex"]
    written[0].write_text(f"<!-- {caption} -->\n" + markdown_table(study.rows, digits))
    written[1].write_text(latex_table(study.rows, digits, caption))
    if plots and study.rows:
        from . import plots as plotting  # matplotlib only when plots are asked for
        written += plotting.write_all(study.rows, folder, proven=proven_rates(cfg), title=title(study, cfg))
    return written


def proven_rates(cfg):
    """{norm column: the rate the paper proves for this study's case} (rates.PAPER_RATES through the
    verdict's lookup); empty when unknown."""
    if cfg is None:
        return {}
    from . import config, verdict
    found = {norm: verdict.expected(cfg, norm).rate for norm in config.ERROR_NORMS + config.REFERENCE_NORMS}
    return {norm: rate for norm, rate in found.items() if rate is not None}


def title(study, cfg=None):
    """A one-line plot title: dimension, alpha and the eps law, or the study name alone."""
    if cfg is None:
        return study.name
    if cfg.study_type == "signorini":  # the variational inequality: no alpha, no eps (docs/limit.md)
        return rf"{study.name}: $d = {cfg.dimension}$, Signorini variational inequality ($\varepsilon = 0$)"
    law = {"theta_h": r"\theta h", "theta_sqrt_h": r"\theta\sqrt{h}", "constant": r"\theta",
           "power": rf"\theta h^{{{cfg.epsilon.exponent:g}}}"}[cfg.epsilon.law]
    return (rf"{study.name}: $d = {cfg.dimension}$, $\alpha = {cfg.alpha:g}$, "
            rf"$\varepsilon = {law}$, $\theta = {cfg.epsilon.theta:g}$")


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
        from . import plots  # matplotlib only when plots are asked for
        finest = max(row["N"] for row in named["sweep"])
        rows = [row for row in named["sweep"] if row["N"] == finest]
        written += [plots.model_error(rows, cfg.output_dir / f"model_error{suffix}") for suffix in (".png", ".pdf")]
    return written


def limit_summary(cfg, named, written):
    """The terminal text of an ε-sweep or total-error study: its reference, fitted or total table."""
    lines = [f"study {cfg.study} ({cfg.study_type}): {cfg.output_dir}"]
    for name in ("reference", "fitted", "total"):
        if name in named:
            lines.append(f"\n{name}:\n{format_rows(named[name])}")
    names = [f"{name}.csv" for name in named] + [str(path.relative_to(cfg.output_dir)) for path in written]
    lines.append("wrote " + (", ".join(names) if len(names) <= 4 else f"{len(names)} tables and figures "
                             "(rates.md, rates.tex, plots) in the sub-study folders"))
    return "\n".join(lines)


def format_rows(rows):
    """A right-aligned text table: floats .3e, rates and fitted slopes .2f, '-' for missing values."""
    if not rows:
        return "(nothing solved)"
    columns = list(rows[0])
    cells = [[_row_cell(c, row[c]) for c in columns] for row in rows]
    widths = [max(len(c), *(len(line[i]) for line in cells)) for i, c in enumerate(columns)]
    lines = ["  ".join(c.rjust(w) for c, w in zip(columns, widths))]
    lines += ["  ".join(cell.rjust(w) for cell, w in zip(line, widths)) for line in cells]
    return "\n".join(lines)


def _row_cell(column, value):
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "NO"
    if column in ("alpha", "p"):
        return f"{value:g}"
    if column.startswith(("rate_", "fit_")) or column == "time_s":
        return f"{value:.2f}"
    if isinstance(value, float):
        return f"{value:.3e}"
    return str(value)
