"""A level's record and what a study type gives the record and the report: its tables (rows computed
here once, rates included) and the figures and LaTeX tables the report draws from them."""
from dataclasses import dataclass, field

from ..analysis import rates
from ..solve import solver

NORMS = ("L2", "H1")  # the errors against the exact solution every level measures when it has one
# the columns every rate table (rates.csv) starts with, in this order
LEADING_COLUMNS = ("level", "N", "h", "dofs", "epsilon", "converged", "newton_its",
                   "L2", "rate_L2", "H1", "rate_H1", "time_s")
EXTRA_COLUMNS = ("reason", "linear_its", "final_residual")
WORK_PRECISION_COLUMNS = ("norm", "level", "N", "dofs", "error", "time_s", "cumulative_time_s")


@dataclass
class Level:
    """One level's record: mesh size, ε, solver outcome, errors, wall time."""
    index: int
    n: int
    h: float
    dofs: int
    eps: float
    outcome: solver.Outcome
    errors: dict
    time_s: float
    extra: dict = field(default_factory=dict)
    solution: object = field(default=None, repr=False, compare=False)  # u_h, for nested iteration
    timings: dict = field(default_factory=dict, compare=False)  # t_* phases, memory (timing_columns)
    profile: list = field(default_factory=list, repr=False, compare=False)  # the Γ_C pressure (problems.profile)
    scene: object = field(default=None, repr=False, compare=False)  # (Domain, forms) while on_level sees the level


@dataclass(frozen=True)
class Table:
    """A table the report writes as <name>.md and <name>.tex (a name a/b: into the sub-folder a): `paper`
    tables show the columns output.columns chooses (a rate table), the others every column; `terminal`:
    printed at the end of a run."""
    name: str
    rows: list
    paper: bool = False
    terminal: bool = True


@dataclass(frozen=True)
class Figure:
    """A figure the report draws: kind `convergence` (a rate table's rows: convergence, work_precision
    and newton in the folder of `name`), `model_error` (ε-sweep rows of one mesh) or `comparison` (rate
    tables by label, one curve each: compare_convergence, ...)."""
    name: str
    kind: str
    data: object


def rate_table(levels):
    """Rows (dicts in column order) of the rate table: every measured error with its observed rate
    between successive levels (computed here, once per study: the record, report and plots read them)."""
    h = [lv.h for lv in levels]
    ok = [lv.outcome.converged for lv in levels]
    norms = [norm for norm in NORMS if any(norm in lv.errors for lv in levels)]
    extra = [k for k in (levels[0].extra if levels else {}) if f"rate_{k}" in levels[0].extra]
    observed = {norm: rates.observed(h, [lv.errors.get(norm) for lv in levels], ok) for norm in norms}
    observed.update({name: rates.observed(h, [lv.extra.get(name) for lv in levels], ok) for name in extra})
    rows, cumulative = [], 0.0
    for k, lv in enumerate(levels):
        row = {"level": lv.index, "N": lv.n, "h": lv.h, "dofs": lv.dofs, "epsilon": lv.eps,
               "converged": lv.outcome.converged, "newton_its": lv.outcome.newton_its}
        for norm in norms:
            row[norm] = lv.errors.get(norm) if lv.outcome.converged else None
            row[f"rate_{norm}"] = observed[norm][k]
        row["time_s"] = lv.time_s
        row.update(reason=lv.outcome.reason, linear_its=lv.outcome.linear_its,
                   final_residual=lv.outcome.residuals[-1] if lv.outcome.residuals else None)
        row.update(lv.extra)
        row.update({f"rate_{name}": observed[name][k] for name in extra})
        row.update(lv.timings)
        cumulative += lv.time_s or 0.0  # failed levels cost time too
        row["cumulative_time_s"] = cumulative
        rows.append(row)
    return rows


def work_precision_rows(rows):
    """Error against cost, one row per (norm, level) with an error: the level's own wall time and the
    cumulative wall time of the study up to it (what an error costs from scratch)."""
    return [{"norm": norm, "level": row["level"], "N": row["N"], "dofs": row["dofs"], "error": row[norm],
             "time_s": row["time_s"], "cumulative_time_s": row["cumulative_time_s"]}
            for norm in rates.error_columns(rows) for row in rows if row.get(norm) is not None]
