"""The study's record on disk, rewritten atomically after every solve: rates.csv, summary.csv,
work_precision.csv and study.h5 for refinement and signorini studies; sweep.csv, fitted.csv and
reference.csv (ε-sweeps) or total.csv and one folder per sub-study (total error) beside their study.h5."""
import contextlib
import csv
import datetime
import functools
import io
import json
import platform
import subprocess
from pathlib import Path

import numpy as np
import yaml
from mpi4py import MPI

from .. import __version__, config
from ..analysis import rates, verdict
from ..config import canonical, fingerprint
from ..system import files

LEVEL_STUDIES = ("refinement", "signorini")  # a list of Levels, one rate table
SPEC_COLUMNS = ("level", "N", "h", "dofs", "epsilon", "converged", "newton_its",
                "L2", "rate_L2", "H1", "rate_H1", "time_s")
EXTRA_COLUMNS = ("reason", "linear_its", "final_residual")
NORMS = ("L2", "H1")
WORK_PRECISION_COLUMNS = ("norm", "level", "N", "dofs", "error", "time_s", "cumulative_time_s")
# one line: running (k of n levels done) | complete | interrupted at level k | failed at level k: reason
STATUS_FILE = "status.txt"


def table(levels):
    """Rows (dicts in column order) of the rate table; error columns only for norms measured."""
    norms = [norm for norm in NORMS if any(norm in lv.errors for lv in levels)]
    h = [lv.h for lv in levels]
    ok = [lv.outcome.converged for lv in levels]
    observed = {norm: rates.observed(h, [lv.errors.get(norm) for lv in levels], ok) for norm in norms}
    rows = []
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
        row.update(lv.timings)
        rows.append(row)
    cumulative = 0.0
    for row in rows:  # failed levels cost time too
        cumulative += row["time_s"] or 0.0
        row["cumulative_time_s"] = cumulative
    return rows


def is_timing(column):
    """Whether a table column is a measured time or memory (differs from run to run)."""
    return (column in ("time_s", "cumulative_time_s", "peak_memory_mb", "peak_memory_mesh_mb", "floor_ratio",
                       "reference_time_s")
            or column.startswith("t_"))


def work_precision_rows(rows):
    """Error against cost, one row per (norm, level) with an error: the level's own wall time and the
    cumulative wall time of the study up to it (what an error costs from scratch)."""
    return [{"norm": norm, "level": row["level"], "N": row["N"], "dofs": row["dofs"], "error": row[norm],
             "time_s": row["time_s"], "cumulative_time_s": row["cumulative_time_s"]}
            for norm in rates.error_columns(rows) for row in rows if row.get(norm) is not None]


def write(cfg, result, comm=MPI.COMM_WORLD, status=None):
    """Write the study's files (and status.txt, given a status) for the result so far: the Levels of a
    refinement or signorini study, a Sweep or a Total (rank 0 writes, every rank waits); the rows of
    its main table (rates, or the ε-sweep's / total-error table)."""
    summary = verdict.summarize(cfg, result) if cfg.study_type in LEVEL_STUDIES else None
    rows = main_table(cfg, result)
    if comm.rank == 0:
        write_files(cfg, result, rows, comm.size, status, summary)
    comm.barrier()
    return rows


def write_files(cfg, result, rows, mpi_size, status=None, summary=None):
    """The writing of `write` by this rank alone, no collective: the fault path calls it on the rank
    that failed. Every file is written aside first, then all are renamed (status.txt last): a failure
    such as a full disk replaces none of them, so the tables and study.h5 always hold the same solves."""
    if cfg.study_type not in LEVEL_STUDIES:
        return _write_limit_files(cfg, result, mpi_size, status)
    levels = result
    summary = verdict.summarize(cfg, levels) if summary is None else summary
    folder = cfg.output_dir
    folder.mkdir(parents=True, exist_ok=True)
    texts = {"rates.csv": csv_text(rows),
             "summary.csv": csv_text(verdict.summary_rows(summary), verdict.SUMMARY_COLUMNS),
             "work_precision.csv": csv_text(work_precision_rows(rows), WORK_PRECISION_COLUMNS)}
    writes = [(folder / name, functools.partial(Path.write_text, data=text)) for name, text in texts.items()]
    writes.append((folder / "study.h5", lambda path: _write_h5(path, cfg, levels, rows, mpi_size, summary, status)))
    if status is not None:
        writes.append((folder / STATUS_FILE, functools.partial(Path.write_text, data=status + "\n")))
    files.replace_all(writes)


def write_status(folder, status):
    """status.txt alone, in place: when the results cannot be written (a full disk), it still says why."""
    files.overwrite(Path(folder) / STATUS_FILE, status + "\n")


def main_table(cfg, result):
    """The rows of the study's main table: the rate table, or the first of limit_tables."""
    if cfg.study_type in LEVEL_STUDIES:
        return table(result)
    return next(iter(limit_tables(cfg, result).values()), [])


def _write_limit_files(cfg, result, mpi_size, status):
    """An ε-sweep's or total-error study's CSV tables and study.h5 (a total-error study also writes each
    sub-study's rate table in its own folder); status.txt last."""
    if cfg.study_type == "total_error" and not isinstance(result, list):
        for sub, levels in result.studies.values():
            if levels:
                write_files(sub, levels, table(levels), mpi_size)
    named = limit_tables(cfg, result)
    folder = cfg.output_dir
    folder.mkdir(parents=True, exist_ok=True)
    writes = [(folder / f"{name}.csv", functools.partial(Path.write_text, data=csv_text(rows)))
              for name, rows in named.items()]
    writes.append((folder / "study.h5", lambda path: _write_limit_h5(path, cfg, named, mpi_size, status)))
    if status is not None:
        writes.append((folder / STATUS_FILE, functools.partial(Path.write_text, data=status + "\n")))
    files.replace_all(writes)


def _write_limit_h5(path, cfg, named, mpi_size, status):
    with _h5_in_memory(path) as h5:
        _write_attrs(h5, cfg, mpi_size, status)
        h5.attrs["study_type"] = cfg.study_type
        for name, rows in named.items():
            _write_table(h5.create_group(name), rows)


# --- the ε → 0 studies' tables (docs/limit.md) -------------------------------------------------------
MODEL_ERRORS = ("L2", "H1", "L2_gamma_c", "penetration")  # of u_{ε,h} − u_{S,h} (measure.model_differences)
SWEEP_COLUMNS = ("N", "h", "dofs", "alpha", "epsilon", "converged", "newton_its",
                 "L2", "rate_L2", "H1", "rate_H1", "L2_gamma_c", "rate_L2_gamma_c",
                 "penetration", "rate_penetration", "time_s", "reason")


def limit_tables(cfg, result):
    """The CSV tables of an ε-sweep (sweep, fitted, reference) or a total-error study (total): name -> rows
    (none before the first solve, when the result is still the empty list the study starts from)."""
    if isinstance(result, list):
        return {}
    if cfg.study_type == "epsilon_sweep":
        return {"sweep": sweep_table(result), "fitted": fitted_table(result, cfg.limit.fit_last),
                "reference": table(result.references)}
    return {"total": total_table(result, cfg.limit.fit_last)}


def sweep_table(sweep):
    """One row per (mesh, α, ε): the differences and their rates in ε against the previous ε."""
    rows = []
    for group in _sweep_groups(sweep.points):
        eps = [p.eps for p in group]
        ok = [p.outcome.converged for p in group]
        observed = {m: rates.observed(eps, [p.differences[m] for p in group], ok) for m in MODEL_ERRORS}
        for k, p in enumerate(group):
            row = {"N": p.n, "h": p.h, "dofs": p.dofs, "alpha": p.alpha, "epsilon": p.eps,
                   "converged": p.outcome.converged, "newton_its": p.outcome.newton_its}
            for m in MODEL_ERRORS:
                row[m] = p.differences[m] if ok[k] else None
                row[f"rate_{m}"] = observed[m][k]
            row.update(time_s=p.time_s, reason=p.outcome.reason)
            rows.append(row)
    return rows


def fitted_table(sweep, last):
    """One row per (mesh, α): the least-squares slope of log(difference) against log ε over the
    `last` smallest converged ε, for every measure."""
    rows = []
    for group in _sweep_groups(sweep.points):
        eps, ok = [p.eps for p in group], [p.outcome.converged for p in group]
        used = [p for p in group if p.outcome.converged][-last:]
        row = {"N": group[0].n, "h": group[0].h, "alpha": group[0].alpha, "points": len(used),
               "eps_max": used[0].eps if used else None, "eps_min": used[-1].eps if used else None}
        for m in MODEL_ERRORS:
            row[f"fit_{m}"] = rates.fitted(eps, [p.differences[m] for p in group], ok, last)
        rows.append(row)
    return rows


def total_table(total, last):
    """One row per sub-study: its finest level's errors against u_S, the last and the fitted rates."""
    rows = []
    for name, (sub, levels) in total.studies.items():
        finest = table(levels)[-1] if levels else {}
        vi_study = sub.study_type == "signorini"
        row = {"study": name, "solver": "signorini" if vi_study else "compliance",
               "alpha": None if vi_study else sub.alpha, "p": None if vi_study else sub.epsilon.exponent,
               "levels": len(levels), "N": finest.get("N"), "h": finest.get("h"), "epsilon": finest.get("epsilon"),
               "converged": all(lv.outcome.converged for lv in levels)}
        for norm in NORMS:
            row[norm] = finest.get(norm)
            row[f"rate_{norm}"] = finest.get(f"rate_{norm}")
            row[f"fit_{norm}"] = rates.fitted([lv.h for lv in levels], [lv.errors.get(norm) for lv in levels],
                                              [lv.outcome.converged for lv in levels], last)
        rows.append(row)
    return rows


def _sweep_groups(points):
    """The points split into runs of one (mesh, α), in solve order."""
    groups = {}
    for p in points:
        groups.setdefault((p.n, p.alpha), []).append(p)
    return list(groups.values())


def csv_text(rows, columns=None):
    """The table as CSV: floats in full precision, empty cells for missing values; `columns`
    defaults to every row's keys, in order of appearance (rows lacking a column leave it empty)."""
    if not rows and columns is None:
        return ""
    out = io.StringIO()
    columns = columns or list(dict.fromkeys(key for row in rows for key in row))
    writer = csv.DictWriter(out, fieldnames=list(columns), lineterminator="\n", restval="")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: _cell(v) for k, v in row.items()})
    return out.getvalue()


def _cell(value):
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return value


def versions():
    """Versions of the package and of the numerical stack, for the record."""
    import basix, dolfinx, ffcx, h5py, numpy, ufl  # the record's versions: imported only when written
    from petsc4py import PETSc
    return {"signorini": __version__, "dolfinx": dolfinx.__version__, "basix": basix.__version__,
            "ffcx": ffcx.__version__, "ufl": ufl.__version__, "h5py": h5py.__version__,
            "numpy": numpy.__version__, "petsc": ".".join(map(str, PETSc.Sys.getVersion())),
            "python": platform.python_version()}


def _write_h5(path, cfg, levels, rows, mpi_size, summary=None, status=None):
    with _h5_in_memory(path) as h5:
        _write_attrs(h5, cfg, mpi_size, status)
        h5.attrs["levels_done"] = len(levels)
        h5.attrs["config_hash"] = fingerprint(cfg)  # --resume continues only under the same hash
        h5.attrs["config_canonical"] = json.dumps(canonical(cfg), sort_keys=True, default=str)
        h5.attrs["time_total_s"] = float(sum(lv.time_s for lv in levels))
        _write_table(h5.create_group("table"), rows)
        for lv, row in zip(levels, rows):
            _write_level(h5.create_group(f"level_{lv.index:02d}"), lv, row)
        if summary is not None:
            verdict.write_h5(h5.create_group("verification"), summary)


@contextlib.contextmanager
def _h5_in_memory(path):
    """An HDF5 file built in memory, then written to `path` as bytes: a full disk is then a plain OSError,
    never an HDF5 file left half-closed (h5py raises RuntimeError and HDF5 crashes with SEGV at exit)."""
    import h5py
    buffer = io.BytesIO()
    with h5py.File(buffer, "w") as h5:
        yield h5
    Path(path).write_bytes(buffer.getvalue())


def _write_attrs(h5, cfg, mpi_size, status):
    """What every study.h5 records: the config as given and resolved (--set overrides and defaults
    included), the study, MPI size, status, versions and git revision."""
    h5.attrs["config"] = cfg.text
    h5.attrs["config_resolved"] = yaml.safe_dump(config.to_dict(cfg), sort_keys=False)
    h5.attrs["study"] = cfg.study
    h5.attrs["contact_quadrature"] = str(cfg.contact_quadrature)  # the discrete problem's contact rule
    h5.attrs["mpi_size"] = mpi_size
    h5.attrs["date"] = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    if status is not None:
        h5.attrs["status"] = status
    for name, version in versions().items():
        h5.attrs[f"version_{name}"] = version
    if git_revision():
        h5.attrs["git_revision"] = git_revision()


@functools.lru_cache(maxsize=1)
def git_revision():
    """The commit of the signorini checkout ('+dirty' with uncommitted changes), or '' outside git."""
    source = Path(__file__).resolve().parents[2]
    if not (source / "pyproject.toml").exists():
        return ""  # an installed copy, not a checkout: any repository around it is not ours
    try:
        head = subprocess.run(["git", "-C", str(source), "rev-parse", "HEAD"], capture_output=True,
                              text=True, timeout=10)
        dirty = subprocess.run(["git", "-C", str(source), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.TimeoutExpired):
        return ""
    if head.returncode != 0:
        return ""
    return head.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")


def _write_table(group, rows):
    group.attrs["columns"] = list(rows[0]) if rows else []  # HDF5 lists datasets by name, not in order
    for column in (rows[0] if rows else {}):
        values = [row.get(column) for row in rows]  # a column some rows lack (limit studies) is NaN there
        if all(isinstance(v, str) for v in values):
            group.create_dataset(column, data=[v.encode() for v in values])
        else:
            group.create_dataset(column, data=[float("nan") if v is None else float(v) for v in values])


def _write_level(group, lv, row):
    for column, value in row.items():
        if value is not None:
            group.attrs[column] = value
    group.create_dataset("residuals", data=np.array(lv.outcome.residuals, dtype=float))
    _write_solves(group, lv.outcome.steps)
    for norm, value in lv.errors.items():  # raw errors, also of a level that did not converge
        group.attrs[f"measured_{norm}"] = value


def _write_solves(group, steps):
    """One entry per SNES solve of the level (attempts, continuation steps, linear fallback), in order:
    its eps, Newton iterations and reason; `residuals` holds their histories one after the other."""
    if steps:
        group.create_dataset("solve_eps", data=np.array([s[0] for s in steps], dtype=float))
        group.create_dataset("solve_newton_its", data=np.array([s[1] for s in steps], dtype=int))
        group.create_dataset("solve_reason", data=[s[2].encode() for s in steps])
