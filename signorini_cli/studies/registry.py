"""The study types by name. A study type is one module of this folder that runs its solves and says what
its record and report hold; a new type is a new module and one entry below. Each module has:

    NAME, UNIT ("levels", "solves" or "points": what status.txt counts), RESUMABLE (--resume continues it),
    POINTS (a map: points that are studies of their own, run and recorded by app/maps; the rest below is
    then not needed),
    run(cfg, on_level, comm, monitor, done) -> result (iterating a result gives every solve),
    tables(cfg, result) -> {name: rows}, the main table first ("a/b": in study.h5 only, no CSV),
    summary(cfg, result) -> a verdict.Summary (summary.csv) or None,
    levels_of(result) -> the Levels recorded as level_NN groups of study.h5,
    parts(cfg, result) -> [(config, result)] recorded as studies of their own in sub-folders,
    reported(cfg, tables) -> ([level.Table], [level.Figure]): what the report writes and draws,
    compared(tables) -> {label suffix: rate-table rows}: what `compare` overlays,
    title(cfg, name) -> a one-line figure title.

`run` is the one runner of a study (the command, the Python API and the record's watch use it): it hands on
and returns a `Study`, the result with its tables and verdict computed once.
"""
from dataclasses import dataclass

from mpi4py import MPI

from ..problems import registry as problems

from . import rate_map, refinement, signorini, sweep, total

STUDY_TYPES = {module.NAME: module for module in (refinement, signorini, sweep, total, rate_map)}


def of(name):
    """The module of study type `name` (KeyError for a type this version does not know)."""
    return STUDY_TYPES[name]


@dataclass(frozen=True)
class Study:
    """A study's result so far: its config, what the study type returned (Levels, a Sweep or a Total), its
    tables (name -> rows, the main one first) and its verdict (a verdict.Summary, or None for types without
    one), the tables and verdict computed once from the result as it stood."""
    config: object
    result: object
    tables: dict
    summary: object = None

    @property
    def rows(self):
        """The rows of the main table ([] before any)."""
        return next(iter(self.tables.values()), [])

    @property
    def solves(self):
        """How many solves the result holds."""
        return len(list(self.result))

    @property
    def converged(self):
        """Whether every solve converged."""
        return all(solve.outcome.converged for solve in self.result)

    @property
    def met(self):
        """Whether the user's `expect:` rates were met (True without a verdict or an `expect:` block)."""
        return self.summary is None or self.summary.met


def study_of(cfg, result, summary=None):
    """The Study of `result` (levels are copied into a list: later levels do not join it); `summary`, when the
    verdict of the same solves is known already (the tables alone are built again: timings grew)."""
    kind = of(cfg.study_type)
    result = list(result) if isinstance(result, (list, tuple)) else result
    return Study(cfg, result, kind.tables(cfg, result), kind.summary(cfg, result) if summary is None else summary)


def run(cfg, on_study=None, comm=MPI.COMM_WORLD, monitor=None, done=(), solve_cfg=None):
    """Run cfg's study (solve_cfg: the config the solves use when it differs from the recorded one, as with
    PETSc monitors) and return its Study; on_study(study) after every solve, while the last level's u_h
    (Level.solution) is still there. The last Study handed on is returned when no solve came after it."""
    built = []

    def each(result):
        built[:] = [study_of(cfg, result)]
        on_study(built[0])

    result = run_study(solve_cfg or cfg, each if on_study is not None else None, comm, monitor, done)
    if built and built[0].solves == len(list(result)):
        return built[0]
    return study_of(cfg, result)


def run_study(cfg, on_level=None, comm=MPI.COMM_WORLD, monitor=None, done=()):
    """Run the study of type cfg.study_type; call on_level(result_so_far) after every solve; return
    the result: a list of Levels (refinement, signorini), a Sweep or a Total.
    `monitor(snes, its, fnorm)`, if given, is called at every Newton iteration (progress).
    `done`: the levels a resumed study already has, kept as they are and not solved again.
    Its data are checked at interior points once per mesh family (problems.registry.checked_once)."""
    with problems.checked_once():
        return of(cfg.study_type).run(cfg, on_level, comm, monitor, done)
