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
"""
from mpi4py import MPI

from ..problems import registry as problems

from . import rate_map, refinement, signorini, sweep, total

STUDY_TYPES = {module.NAME: module for module in (refinement, signorini, sweep, total, rate_map)}


def of(name):
    """The module of study type `name` (KeyError for a type this version does not know)."""
    return STUDY_TYPES[name]


def run_study(cfg, on_level=None, comm=MPI.COMM_WORLD, monitor=None, done=()):
    """Run the study of type cfg.study_type; call on_level(result_so_far) after every solve; return
    the result: a list of Levels (refinement, signorini), a Sweep or a Total.
    `monitor(snes, its, fnorm)`, if given, is called at every Newton iteration (progress).
    `done`: the levels a resumed study already has, kept as they are and not solved again.
    Its data are checked at interior points once per mesh family (problems.registry.checked_once)."""
    with problems.checked_once():
        return of(cfg.study_type).run(cfg, on_level, comm, monitor, done)
