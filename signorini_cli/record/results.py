"""The study's record on disk, rewritten atomically after every solve and read back: its tables as CSV
(rates.csv, work_precision.csv, summary.csv; sweep.csv, fitted.csv, reference.csv; total.csv), study.h5
and status.txt, a study of a type with parts (total error) also each part's record in its own folder.
What the tables hold is the study type's (studies.registry); the formats are csvfile's and h5's."""
import datetime
import functools
import json
import logging
import math
import platform
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

from mpi4py import MPI

from .. import __version__, config, studies
from ..analysis import verdict
from ..config import canonical, fingerprint
from ..studies.level import WORK_PRECISION_COLUMNS
from ..system import files
from . import csvfile, h5

logger = logging.getLogger(__name__)
# one line: running (k of n levels done) | complete | interrupted at level k | failed at level k: reason
STATUS_FILE = "status.txt"
# the header a table without rows still has (the CSV of a study before its first error)
EMPTY_HEADERS = {"work_precision": WORK_PRECISION_COLUMNS}


def is_timing(column):
    """Whether a table column is a measured time or memory (differs from run to run)."""
    return (column in ("time_s", "cumulative_time_s", "peak_memory_mb", "peak_memory_mesh_mb", "floor_ratio",
                       "reference_time_s")
            or column.startswith("t_"))


def write(study, comm=MPI.COMM_WORLD, status=None):
    """Write the files of a studies.Study (and status.txt, given a status) (rank 0 writes, every rank
    waits); the rows of its main table."""
    if comm.rank == 0:
        write_files(study, comm.size, status)
    comm.barrier()
    return study.rows


def write_files(study, mpi_size, status=None):
    """The writing of `write` by this rank alone, no collective: the fault path calls it on the rank
    that failed. Every file is written aside first, then all are renamed (status.txt last): a failure
    such as a full disk replaces none of them, so the tables and study.h5 always hold the same solves."""
    cfg, named, summary = study.config, study.tables, study.summary
    kind = studies.of(cfg.study_type)
    for sub, part in kind.parts(cfg, study.result):
        write_files(studies.study_of(sub, part), mpi_size)
    folder = cfg.output_dir
    folder.mkdir(parents=True, exist_ok=True)
    texts = {name: csvfile.text(rows) for name, rows in named.items() if "/" not in name}
    summary_rows = summary_record(summary) if summary is not None else ()
    if summary is not None:
        texts["summary"] = csvfile.text(verdict.summary_rows(summary), verdict.SUMMARY_COLUMNS)
    texts = {name: (text or csvfile.text([], EMPTY_HEADERS.get(name))) for name, text in texts.items()}
    writes = [(folder / f"{name}.csv", functools.partial(Path.write_text, data=text)) for name, text in texts.items()]
    levels = kind.levels_of(study.result)
    attrs = record_attrs(cfg, levels, mpi_size, status)
    writes.append((folder / h5.NAME, lambda path: h5.write(path, attrs, named, zip(levels, study.rows),
                                                            summary_rows)))
    if status is not None:
        writes.append((folder / STATUS_FILE, functools.partial(Path.write_text, data=status + "\n")))
    files.replace_all(writes)


def summary_record(summary):
    """(attributes, rows) of the verdict as study.h5 holds it."""
    head = {"fit_levels": summary.fit_levels, "tolerance": summary.tolerance, "expectations_met": summary.met,
            "outside_theory": summary.outside_theory}
    if summary.notes:
        head["notes"] = "\n".join(summary.notes)
    return head, verdict.summary_rows(summary)


def write_status(folder, status):
    """status.txt alone, replaced whole (a run or report reading it meanwhile sees the old line or the new),
    else in place: when no new file fits (a full disk), it still says why."""
    path = Path(folder) / STATUS_FILE
    try:
        files.replace(path, functools.partial(Path.write_text, data=status + "\n"))
    except OSError:
        files.overwrite(path, status + "\n")


def read_status(folder):
    """A study folder's status.txt line ('' when absent, also when another run removes it as it is read)."""
    try:
        return (Path(folder) / STATUS_FILE).read_text().strip()
    except FileNotFoundError:
        return ""


def restore(cfg, levels, status, mpi_size):
    """A run refused as bad input once under way leaves its folder as it found it: the `levels` it resumed
    with their status line, or no results at all."""
    if levels:
        write_files(studies.study_of(cfg, levels), mpi_size, status or None)
    else:
        start_over(cfg.output_dir)


# what a run writes into its study folder (record.results, report.tables and plots, studies.fields)
RESULT_FILES = ("*.csv", "*.h5", "*.md", "*.tex", "*.png", "*.pdf", STATUS_FILE, "fields/*.xdmf", "fields/*.h5")


def start_over(folder, also=()):
    """Remove a study's old results (--force): the new run's tables and figures never sit beside the old
    ones, also when it is interrupted. Only the files a run writes (and the names `also`), in case the
    folder holds others."""
    for pattern in RESULT_FILES + tuple(also):
        for path in Path(folder).glob(pattern):
            path.unlink()
    fields = Path(folder) / "fields"
    if fields.is_dir() and not any(fields.iterdir()):
        fields.rmdir()


def record_attrs(cfg, levels, mpi_size, status):
    """What every study.h5 records: the config as given and resolved (--set overrides and defaults
    included), its hash for --resume, the study, MPI size, status, versions and git revision."""
    attrs = {"study": cfg.study, "study_type": cfg.study_type, "config": cfg.text,
             "config_resolved": config.yaml_dump(config.to_dict(cfg), allow_unicode=False),
             "config_hash": fingerprint(cfg),  # --resume continues only under the same hash
             "config_canonical": json.dumps(canonical(cfg), sort_keys=True, default=str),
             "contact_quadrature": str(cfg.contact_quadrature),  # the discrete problem's contact rule
             "levels_done": len(levels), "mpi_size": mpi_size,
             "time_total_s": float(sum(lv.time_s for lv in levels)),
             "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}
    if status is not None:
        attrs["status"] = status
    attrs.update({f"version_{name}": version for name, version in versions().items()})
    if git_revision():
        attrs["git_revision"] = git_revision()
    return attrs


def versions():
    """Versions of the package and of the numerical stack, for the record."""
    import basix, dolfinx, ffcx, h5py, numpy, ufl  # the record's versions: imported only when written
    from petsc4py import PETSc
    return {"signorini": __version__, "dolfinx": dolfinx.__version__, "basix": basix.__version__,
            "ffcx": ffcx.__version__, "ufl": ufl.__version__, "h5py": h5py.__version__,
            "numpy": numpy.__version__, "petsc": ".".join(map(str, PETSc.Sys.getVersion())),
            "python": platform.python_version()}


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



# --- reading a study back ---------------------------------------------------------------------------

class DamagedResults(OSError):
    """A study file that cannot be read as a table (cut short, NaN where a count belongs, a group
    missing): bad input for report, compare and --resume, which name the file."""


@dataclass(frozen=True)
class Study:
    """A study read back from its folder: its main table's rows, its name and type, the resolved config
    text, every table of its record (name -> rows) and its root attributes."""
    name: str
    folder: Path
    rows: list
    config_text: str = ""  # empty when read from rates.csv alone
    attrs: dict = field(default_factory=dict, repr=False)
    study_type: str = "refinement"
    tables: dict = field(default_factory=dict, repr=False)


def load(path):
    """Read a study from its folder, its study.h5 or its rates.csv (no recomputation). A damaged
    study.h5 gives way to an intact rates.csv beside it (a warning says so)."""
    path = Path(path)
    if path.is_dir():
        found = path / h5.NAME, path / "rates.csv"
        if not any(p.exists() for p in found):
            raise FileNotFoundError("neither study.h5 nor rates.csv in this folder (not a study folder)")
        path = next(p for p in found if p.exists())
    if not path.exists():
        raise FileNotFoundError("No such file or folder")
    if path.suffix == ".csv":
        return load_csv(path)
    try:
        return load_h5(path)
    except DamagedResults as err:
        fallback = path.parent / "rates.csv"
        if not fallback.exists():
            raise
        try:
            study = load_csv(fallback)
        except DamagedResults as also:
            raise DamagedResults(f"{err}; {also}") from None
        logger.warning("%s; reading %s instead", err, fallback)
        return study


def load_h5(path):
    """The Study in a study.h5: its tables by name (the main one as `rows`)."""
    record = read_record(path)
    attrs = record.attrs
    kind = attrs.get("study_type", "refinement")
    if kind not in studies.STUDY_TYPES:
        raise DamagedResults(f"{path}: damaged, study_type {kind!r} is not one this version knows")
    if record.main is None:
        raise DamagedResults(f"{path}: damaged, no table group")
    tables = record.tables
    if record.main == h5.MAIN:  # written before the main table carried its name: the type's first table
        first = next(iter(studies.of(kind).tables(None, [])), h5.MAIN)
        tables = dict({first: tables.pop(h5.MAIN)}, **tables)
    first = next(iter(tables))
    main = tables[first] = _with_level_attrs(tables[first], record.levels)
    _check_rows(main, path, studies.of(kind).UNIT)
    try:
        studies.of(kind).reported(None, tables)  # every table its type reports is there
    except KeyError as err:
        raise DamagedResults(f"{path}: damaged, no table {err} (study_type {kind})") from None
    text = attrs.get("config_resolved") or attrs.get("config", "")
    return Study(attrs.get("study", path.parent.name), path.parent, main, text, attrs, kind, tables)


def _with_level_attrs(rows, levels):
    """The rows with the values of their level_NN groups' attributes (native types also in files that
    stored every table column as float)."""
    if len(levels) != len(rows):
        return rows
    return [{c: attrs.get(c, value) for c, value in row.items()}
            for row, (attrs, _) in zip(rows, (levels[k] for k in sorted(levels)))]


def read_record(path):
    try:
        return h5.read(path)
    except h5.Damaged as err:
        raise DamagedResults(str(err)) from None


def load_csv(path):
    """The Study of a rates.csv alone (no config, no other table)."""
    try:
        rows = csvfile.read(path)
    except csvfile.Damaged as err:
        raise DamagedResults(str(err)) from None
    _check_rows(rows, path, "levels")
    return Study(path.parent.name, path.parent, rows)


# what every row of a study's rate table holds, whatever else it has
ROW_TYPES = {"level": int, "N": int, "dofs": int, "h": float, "converged": bool}


def _check_rows(rows, path, unit):
    """Raise DamagedResults naming `path` unless every row of a rate table (unit: levels) has its level's
    counts and a finite h > 0."""
    for row in rows if unit == "levels" else ():
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
