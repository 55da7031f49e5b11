"""study.h5, written and read here alone: the study's tables (one dataset per column), one group per level,
the verdict and the record of the run. Every dataset and attribute-bearing group carries `units` and a
one-line `description`, so that h5dump alone explains the file; `describe()` is its documentation."""
import contextlib
import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..studies.level import LEADING_COLUMNS

NAME = "study.h5"
MAIN = "table"  # the group of the study's main table (rates.csv, sweep.csv or total.csv)
MISSING_INT = -1  # an integer column's empty cell (a count is never negative); its `missing` attribute says so

# the root's attributes: name -> (units, description)
ROOT = {
    "study": ("", "the study name (`study:` of the config)"),
    "study_type": ("", "refinement | signorini | epsilon_sweep | total_error: what the tables hold"),
    "config": ("", "the YAML text of the config file as given"),
    "config_resolved": ("", "the config actually run, as YAML: overrides applied, every default filled in"),
    "config_hash": ("", "sha256 of the validated config; --resume continues only under the same hash"),
    "config_canonical": ("", "the validated config as JSON, to name the keys that changed"),
    "contact_quadrature": ("", "the discrete problem's contact rule: exact, vertex or a Gauss degree"),
    "levels_done": ("1", "number of level_NN groups (fewer than the config's levels for a stopped study)"),
    "mpi_size": ("1", "number of MPI ranks of the run"),
    "time_total_s": ("s", "wall time of all levels so far (sum of time_s)"),
    "date": ("", "when the file was written (UTC, ISO 8601)"),
    "status": ("", "the study's status, as in status.txt"),
    "git_revision": ("", "commit of the signorini checkout that ran (+dirty: uncommitted changes)"),
    "version_<name>": ("", "version of signorini, dolfinx, basix, ffcx, ufl, h5py, numpy, petsc, python"),
}
# a table column -> (units, description); `1` is dimensionless, `length` the unit of the mesh coordinates
COLUMNS = {
    "level": ("1", "the level's index, 0 the coarsest mesh"),
    "N": ("1", "cells per side (mesh.refinements; gmsh and file meshes: the number of cells)"),
    "h": ("length", "the largest cell diameter, max over ranks"),
    "dofs": ("1", "global number of unknowns"),
    "epsilon": ("1", "the level's ε = law(h) (0: the Signorini inequality)"),
    "converged": ("", "the SNES outcome (FALSE/TRUE)"),
    "reason": ("", "PETSc's converged or diverged reason"),
    "newton_its": ("1", "Newton iterations of the level"),
    "linear_its": ("1", "Krylov iterations, total over the level"),
    "final_residual": ("1", "||F(u_h)||_2 at the last Newton iterate (carries 1/ε: large for tiny ε)"),
    "time_s": ("s", "the level's wall time (mesh to measures), max over ranks; not t_output, a reference solve "
                    "or the linear floor"),
    "cumulative_time_s": ("s", "time_s summed over the levels so far"),
    "L2": ("1", "||u - u_h|| in L2(Ω) (manufactured scenes)"),
    "H1": ("1", "|u - u_h| in H1(Ω), the seminorm (manufactured scenes)"),
    "L2_gc": ("1", "||u - u_h|| in L2(Γ_C); each facet cut where u, u_h or u - u_h changes sign, tanh-sinh on each "
                   "piece (to round-off, ~1e-14 relative on triangles)"),
    "pos_gc": ("1", "||[u]_+ - [u_h]_+|| in L^{α+1}(Γ_C); each facet cut where u, u_h or u - u_h changes sign, "
                    "tanh-sinh on each piece (to round-off, ~1e-14 relative on triangles)"),
    "pos_gc_scaled": ("1", "pos_gc to the power (α+1)/2 (paper Corollary 3.2 ii)"),
    "energy_err": ("1", "(H1² + pos_gc^{α+1}/ε)^{1/2}, the energy error of paper Lemma 3.1 (pos_gc's rule)"),
    "diff_L2": ("1", "||u_h - u_{h'}|| in L2(Ω) against the previous level's solution"),
    "diff_H1": ("1", "|u_h - u_{h'}| in H1(Ω) against the previous level's solution"),
    "penetration": ("length", "max over Γ_C of [u_h]_+ (ε-sweeps: of [u_εh]_+)"),
    "contact_measure": ("length^(d-1)", "measure of the discrete contact set on Γ_C"),
    "contact_force": ("1", "(1/ε) ∫_Γc [u_h]_+^α, the total contact force: P1 in closed form (the solve's rule), "
                           "P2 cut at the zeros of its quadratic, tanh-sinh on each piece"),
    "half_width": ("length", "the contact half-width: largest distance of the contact set's edge from its centre"),
    "half_width_hertz": ("length", "Hertz's half-width under the measured contact force"),
    "half_width_err": ("1", "|half_width - half_width_hertz| / half_width_hertz"),
    "peak_pressure": ("1", "the central pressure: (1/ε)[u_h·n - g0]_+^α averaged with the weight (1 - (2r/a)²)_+² "
                      "over the middle of the contact zone, over Hertz's profile's same mean (= p0 for Hertz)"),
    "peak_pressure_hertz": ("1", "Hertz's peak pressure under the measured contact force"),
    "peak_pressure_err": ("1", "|peak_pressure - peak_pressure_hertz| / peak_pressure_hertz"),
    "force_hertz": ("1", "Hertz's force for the measured half-width"),
    "force_err": ("1", "|contact_force - force_hertz| / force_hertz"),
    "contact_nodes": ("1", "vertices of Γ_C in contact (the Signorini inequality's active set)"),
    "pressure_max": ("1", "the largest contact pressure on Γ_C"),
    "pressure_L2": ("1", "the contact pressure's error in L2(Γ_C)"),
    "energy": ("1", "the energy of u_h; its Γ_C term by contact_force's rule"),
    "reference_time_s": ("s", "wall time of the level's reference solve (not part of time_s)"),
    "contact_quadrature": ("", "the contact term's rule the level solved with"),
    "target_size": ("length", "the gmsh target cell size"),
    "h_min": ("length", "the smallest cell diameter"),
    "gamma_c_measure": ("length^(d-1)", "|Γ_C| of the discrete mesh"),
    "gamma_c_quasi_uniformity": ("1", "max h_F / min h_F over the facets of Γ_C"),
    "continuation_steps": ("1", "SNES solves of the ε-continuation, 0 without"),
    "linear_fallback": ("", "an iterative linear solve failed and the level went on with MUMPS (FALSE/TRUE)"),
    "final_correction": ("1", "the last Newton correction over ||u_h||: the solve's own error estimate"),
    "condition": ("1", "λ_max/λ_min of the Jacobian at u_h on the free dofs (small levels only)"),
    "peak_memory_mb": ("MiB", "peak resident set size so far (max over ranks), at the level's end"),
    "peak_memory_mesh_mb": ("MiB", "peak resident set size so far, right after the level's mesh"),
    "t_linear_floor": ("s", "one assembly and linear solve of the Jacobian at u_h (solver.linear_floor)"),
    "floor_ratio": ("1", "t_newton / t_linear_floor"),
    "alpha": ("1", "the exponent α of [u]_+^α"),
    "L2_gamma_c": ("1", "||u_εh - u_Sh|| in L2(Γ_C)"),
    "points": ("1", "converged ε the fit used"),
    "eps_max": ("1", "the largest ε of the fit"),
    "eps_min": ("1", "the smallest ε of the fit"),
    "study": ("", "the sub-study (its folder beside study.h5)"),
    "solver": ("", "compliance or signorini: what the sub-study solves"),
    "p": ("1", "the exponent of ε = θ h^p"),
    "levels": ("1", "levels the sub-study solved"),
    "norm": ("", "the error norm of the row"),
    "x": ("length", "the node's coordinate along Γ_C (2-D: along the tangent of its mean normal)"),
    "r": ("length", "the node's distance from the contact set's centre across Γ_C's mean normal (3-D)"),
    "pressure": ("1", "the contact pressure (1/ε)[w_h]_+^α at the node, w = u (scalar) or u·n - g0 (elasticity)"),
    "pressure_exact": ("1", "(1/ε)[w_ex]_+^α of the exact solution at the node"),
    "error": ("1", "the error in that norm"),
}
TABLES = {
    "table": "the study's main table: rates.csv (sweep.csv, total.csv for the ε → 0 studies), row k = level k",
    "work_precision": "error against cost (work_precision.csv): one row per error norm and level",
    "fitted": "per mesh and α: the slope of log(model error) against log ε (fitted.csv)",
    "reference": "per mesh: the Signorini solution u_Sh the sweep is measured against (reference.csv)",
    "studies": "each sub-study's rate table, as the rates.csv in its folder",
    "pressure": "the contact pressure at the Γ_C nodes of every level (pressure.csv), sorted along Γ_C",
}
LEVEL = ("the level's row of /table as attributes (units: the /table dataset of the same name); measured_<norm>: "
         "the error as measured, also where the level did not converge")
LEVEL_DATASETS = {
    "residuals": ("1", "the nonlinear residual norms of every Newton iteration of the level, solve after solve"),
    "solve_eps": ("1", "ε of each SNES solve of the level (attempts, continuation steps), in order"),
    "solve_newton_its": ("1", "Newton iterations of each SNES solve"),
    "solve_reason": ("", "PETSc's reason of each SNES solve"),
}
VERIFICATION = ("the verdict (summary.csv): one subgroup per norm, quantity and `expect:` rate, "
                "its fields as attributes")


def column_info(column):
    """(units, description) of a table column, also of the families rate_X, fit_X, X_ref, t_X."""
    if column in COLUMNS:
        return COLUMNS[column]
    for prefix, what in (("rate_", "observed rate of {} between successive levels (sweeps: successive ε)"),
                         ("fit_", "least-squares slope of log {} over the last levels (sweeps: smallest ε)")):
        if column.startswith(prefix):
            return "1", what.format(column[len(prefix):])
    if column.endswith("_ref"):
        units, what = column_info(column[:-4])
        return units, what.replace("u -", "u_ref -").replace("[u]_+", "[u_ref]_+") + ", u_ref a finer solution"
    if column.startswith("t_"):
        return "s", f"wall time of the level's phase {column[2:]} (max over ranks)"
    return "", column.replace("_", " ")


# --- writing ----------------------------------------------------------------------------------------

def write(path, attrs, named, levels=(), summary_rows=(), solves=None):
    """study.h5 at `path`: root attributes `attrs`, every table of `named` (name -> rows; the first is the
    main one, in /table), a level_NN group per (Level, row) of `levels`, the verdict's rows."""
    with _in_memory(path) as h5:
        _describe(h5, "the record of one signorini study", ROOT, attrs)
        for name, rows in named.items():
            _write_table(h5.require_group(MAIN if name == next(iter(named)) else name), rows, name)
        for lv, row in levels:
            _write_level(h5.create_group(f"level_{lv.index:02d}"), lv, row)
        if summary_rows:
            _write_summary(h5.create_group("verification"), *summary_rows)


@contextlib.contextmanager
def _in_memory(path):
    """An HDF5 file built in memory, then written to `path` as bytes: a full disk is then a plain OSError,
    never an HDF5 file left half-closed (h5py raises RuntimeError and HDF5 crashes with SEGV at exit)."""
    import h5py
    buffer = io.BytesIO()
    with h5py.File(buffer, "w") as h5:
        yield h5
    Path(path).write_bytes(buffer.getvalue())


def _describe(node, description, known, attrs=None):
    """Set `attrs` on the node, then its description and the units of every attribute that has one."""
    for key, value in (attrs or {}).items():
        node.attrs[key] = value
    node.attrs["description"] = description
    units = [f"{key}: {known[key][0]}" for key in (attrs or known) if key in known and known[key][0]]
    node.attrs["units"] = "; ".join(units)


def _write_table(group, rows, name):
    """One dataset per column, integers and flags as integers, text as strings; `columns` keeps their order."""
    for part in name.split("/"):
        if part in TABLES:
            group.attrs["description"] = TABLES[part]
    group.attrs.setdefault("description", f"the table {name}.csv")
    group.attrs["units"] = "per dataset"
    group.attrs["table"] = name  # its CSV file's name (rates, sweep, ...), also for the main table
    columns = list(dict.fromkeys(key for row in rows for key in row))
    group.attrs["columns"] = columns  # HDF5 lists datasets by name, not in order
    for column in columns:
        data, missing = _column_data([row.get(column) for row in rows])
        dataset = group.create_dataset(column, data=data)
        units, what = column_info(column)
        dataset.attrs["units"], dataset.attrs["description"] = units, what
        if missing is not None:
            dataset.attrs["missing"] = missing


def _column_data(values):
    """(array, the value that marks an empty cell or None): bool -> int8, int -> int64, text -> strings,
    else float64 with NaN for empty cells."""
    present = [v for v in values if v is not None]
    if present and all(isinstance(v, str) for v in present):
        return np.array([(v or "").encode() for v in values], dtype=object).astype("S"), None
    if present and all(isinstance(v, (bool, np.bool_)) for v in present):  # HDF5 enum FALSE = 0, TRUE = 1 (int8)
        if len(present) == len(values):
            return np.array(values, dtype=np.bool_), None
        return np.array([MISSING_INT if v is None else int(v) for v in values], dtype=np.int8), MISSING_INT
    if present and all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in present):
        return np.array([MISSING_INT if v is None else v for v in values], dtype=np.int64), \
            (MISSING_INT if len(present) < len(values) else None)
    return np.array([np.nan if v is None else float(v) for v in values], dtype=np.float64), None


def _write_level(group, lv, row):
    """The row as typed attributes, the raw errors, and the level's Newton history as datasets."""
    for column, value in row.items():
        if value is not None:
            group.attrs[column] = np.bool_(value) if isinstance(value, bool) else value
    for norm, value in lv.errors.items():  # raw errors, also of a level that did not converge
        group.attrs[f"measured_{norm}"] = value
    group.attrs["description"] = LEVEL
    group.attrs["units"] = "those of the /table datasets of the same names"
    datasets = {"residuals": np.array(lv.outcome.residuals, dtype=np.float64)}
    steps = lv.outcome.steps
    if steps:
        datasets.update(solve_eps=np.array([s[0] for s in steps], dtype=np.float64),
                        solve_newton_its=np.array([s[1] for s in steps], dtype=np.int64),
                        solve_reason=np.array([s[2].encode() for s in steps], dtype="S"))
    for name, data in datasets.items():
        dataset = group.create_dataset(name, data=data)
        dataset.attrs["units"], dataset.attrs["description"] = LEVEL_DATASETS[name]


def _write_summary(group, head, rows):
    """The verdict: `head` as attributes, one subgroup per row (its kind, then its name)."""
    for key, value in head.items():
        group.attrs[key] = value
    group.attrs["description"] = VERIFICATION
    group.attrs["units"] = "observed_rate, proven_rate: 1 (powers of h)"
    for row in rows:
        kind = group.require_group(row["kind"])
        kind.attrs["description"] = f"one subgroup per {row['kind']} of the verdict, by its name"
        kind.attrs["units"] = ""
        sub = kind.create_group(row["name"])
        for key, value in row.items():
            if key not in ("kind", "name") and value is not None:
                sub.attrs[key] = value
        sub.attrs["description"] = f"the verdict's {row['kind']} {row['name']}"
        sub.attrs["units"] = "rates: 1"


# --- reading ----------------------------------------------------------------------------------------

class Damaged(OSError):
    """study.h5 cannot be read as a record (cut short, not HDF5, a group or attribute missing or of the
    wrong type): bad input for report, compare and --resume, which name the file."""


@dataclass
class Record:
    """study.h5 read back: root attributes, tables (name -> rows; the main one first: its group is
    `table`) and the level groups by their index (attributes, datasets)."""
    attrs: dict
    tables: dict
    levels: dict = field(default_factory=dict)
    main: str = None  # the main table's name; None when the file has no /table


def read(path):
    """The Record in `path`; Damaged when it is not one."""
    import h5py
    try:
        with h5py.File(path, "r") as h5:
            attrs = {key: plain(value) for key, value in h5.attrs.items()}
            tables, levels = {}, {}
            h5.visititems(lambda name, node: _read_node(name, node, tables, levels))
            main = h5[MAIN].attrs.get("table", MAIN) if MAIN in h5 else None
    except Damaged:
        raise
    except (OSError, KeyError, ValueError, TypeError) as err:  # h5py: truncated, or not HDF5 at all
        raise Damaged(f"{path}: damaged, not readable as HDF5 ({_first_line(err)})") from None
    if main is None or MAIN not in tables:
        return Record(attrs, tables, levels)
    main = plain(main)  # the main table first, under its own name
    return Record(attrs, dict({main: tables.pop(MAIN)}, **tables), levels, main)


def _read_node(name, node, tables, levels):
    import h5py
    if not isinstance(node, h5py.Group):
        return
    if "columns" in node.attrs:
        tables[name if name == MAIN else plain(node.attrs.get("table", name))] = _read_table(node)
    elif name.startswith("level_") and "/" not in name:
        try:
            index = int(name[len("level_"):])
        except ValueError:
            return
        levels[index] = ({k: plain(v) for k, v in node.attrs.items() if k not in ("units", "description")},
                         {k: node[k][()] for k in node if isinstance(node[k], h5py.Dataset)})


def _read_table(group):
    columns = [str(c) for c in group.attrs["columns"]]
    data = {c: [plain(v) for v in group[c][()]] for c in columns}
    for c in columns:
        missing = group[c].attrs.get("missing")
        data[c] = [None if v is None or (missing is not None and v == missing)
                   or (isinstance(v, float) and v != v) else v for v in data[c]]
    return [{c: data[c][k] for c in columns} for k in range(len(data[columns[0]]) if columns else 0)]


def plain(value):
    """numpy scalars and bytes from h5py as Python values (bool, int, float, str)."""
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.ndarray) and value.ndim:
        return [plain(v) for v in value]
    return value.item() if hasattr(value, "item") else value


def _first_line(err):
    return str(err).splitlines()[0] if str(err) else type(err).__name__


def outline(path):
    """(name, kind, units, description) of every group and dataset in `path`, in file order: the file
    explained by its own attributes."""
    import h5py
    found = []

    def visit(name, node):
        kind = "group"
        if isinstance(node, h5py.Dataset):
            kind = f"{'string' if node.dtype.kind in 'SO' else node.dtype}, {node.shape[0] if node.shape else 1}"
        found.append((name, kind, plain(node.attrs.get("units", "")), plain(node.attrs.get("description", ""))))
    try:
        with h5py.File(path, "r") as h5:
            found.append(("/", "group", plain(h5.attrs["units"]), plain(h5.attrs["description"])))
            h5.visititems(visit)
    except (OSError, KeyError) as err:
        raise Damaged(f"{path}: damaged, not readable as HDF5 ({_first_line(err)})") from None
    return found


# --- the documentation ------------------------------------------------------------------------------

def describe():
    """The format of study.h5 as Markdown tables, from the descriptions the writer puts in the file."""
    def table(entries, heading):
        return [f"| {heading} | units | description |", "|---|---|---|"] + [
            f"| `{name}` | {units or '–'} | {what} |" for name, (units, what) in entries.items()]
    families = {f"{p}<X>": column_info(f"{p}X") for p in ("rate_", "fit_", "t_")}
    families["<X>_ref"] = ("1", "X against a finer reference solution u_ref (data-only scenes)")
    lines = ["### Root attributes", ""] + table(ROOT, "attribute") + [
        "", "### Tables", "",
        "A table is a group with the attribute `columns` (the CSV's column order) and one dataset per column,",
        "one entry per row. Counts are `int64`, flags (`converged`, `linear_fallback`) the HDF5 enum FALSE = 0,",
        f"TRUE = 1 on `int8`; an integer column with empty cells has the attribute `missing` = {MISSING_INT}. Other",
        "numbers are `float64`, NaN where the CSV cell is empty; text columns are byte strings.", ""]
    lines += [f"- `{name}`: {what}" for name, what in TABLES.items()]
    lines += ["", f"The rate table's first columns: `{','.join(LEADING_COLUMNS)}`.", "",
              "### Columns", ""] + table(dict(COLUMNS, **families), "column")
    lines += ["", "### Groups `level_00`, `level_01`, …", "", LEVEL + ".", ""] + table(LEVEL_DATASETS, "dataset")
    lines += ["", "### Group `verification`", "", VERIFICATION + "."]
    return "\n".join(lines) + "\n"


def solution_bytes(index, points, values):
    """solution.h5 of a level's u_h (its dofs' points and values, for --resume), as bytes to write atomically."""
    import h5py
    buffer = io.BytesIO()
    with h5py.File(buffer, "w") as out:
        out.attrs["level"] = index
        out.attrs["description"] = "the level's u_h: its dofs' points and values, for --resume"
        out.create_dataset("points", data=points)
        out.create_dataset("values", data=values)
    return buffer.getvalue()


def read_solution(path):
    """(level, points, values) of solution.h5, or None where it cannot be read (then levels are solved again)."""
    import h5py
    try:
        with h5py.File(path, "r") as stored:
            return int(stored.attrs["level"]), stored["points"][...], stored["values"][...]
    except (OSError, KeyError, ValueError):
        return None
