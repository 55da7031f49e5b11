"""The Python API: `load` a config (a YAML file or a mapping) and `run` its study, for notebooks and
scripts. `run` writes no files unless asked; a callback sees each level's solution before it is let go."""
import copy
import dataclasses
from pathlib import Path

from mpi4py import MPI

from .. import config, studies
from ..config import loader, reading
from ..studies import rate_map
from . import guard, maps


Study = studies.Study  # a finished study: config, result, tables (main table: `rows`) and verdict (`summary`)


def load(source, **overrides):
    """The validated Config of a YAML file (path) or a mapping, with keyword overrides: a key's dotted path
    with `__` for the dots (mesh__refinements=[8, 16]), values as Python data. Bad input raises
    config.ConfigError naming the key."""
    if isinstance(source, dict):
        raw, folder = copy.deepcopy(source), None
    else:
        raw, folder = config.yaml_load(loader.read_bounded(source).decode("utf-8")), Path(source).resolve().parent
        if not isinstance(raw, dict):
            raise config.ConfigError("", "the config must be a YAML mapping of keys to values")
    for name, value in overrides.items():
        reading.set_path(raw, name.replace("__", "."), value)
    cfg = config.from_dict(raw, folder)
    return dataclasses.replace(cfg, text=config.yaml_dump(raw))


def run(cfg, on_level=None, comm=MPI.COMM_WORLD, write=False):
    """Run cfg's study on `comm` and return it as a Study (the runner of `signorini run`). on_level(level, u_h),
    if given, is called after each solve of a refinement or signorini study (total_error: of its sub-studies;
    a map: of its points) with the Level and its solution u_h (a dolfinx Function; the mesh is
    u_h.function_space.mesh), before the study lets u_h go. write=True keeps rates.csv, summary.csv, study.h5
    and status.txt in cfg.output_dir current after every solve, as `signorini run` does (its tables and figures
    are the command's), holding the folder's lock as it does; a map is written as `signorini run --force`
    writes it."""
    def each(study):
        if write:
            watch.level_done(study)
        last = list(study.result)[-1] if study.solves else None
        if on_level is not None and getattr(last, "solution", None) is not None:
            on_level(last, last.solution)

    if studies.of(cfg.study_type).POINTS:
        return _run_map(cfg, on_level, comm, write)
    if not write:
        return studies.run(cfg, each if on_level else None, comm)
    with guard.FolderLock(cfg.output_dir, comm), guard.Watch(cfg, (), comm) as watch:
        return studies.run(cfg, each, comm)


def _run_map(cfg, on_level, comm, write):
    """A map's Study: the Points this group of ranks ran, and map.csv's rows of every point as its table."""
    def each(point):
        last = point.levels[-1:]  # also called as a point starts
        if on_level is not None and last and getattr(last[0], "solution", None) is not None:
            on_level(last[0], last[0].solution)

    if write:
        ran = maps.run(cfg, force=True, quiet=True, comm=comm, on_level=each)
    else:
        ran = studies.run_study(cfg, on_level=each, comm=comm)
    mine = [(p.index, rate_map.row(p.cfg, p.values, p.levels, maps.status_of(p), cfg.map.varied))
            for p in ran if p.comm.rank == 0]
    rows = sorted((pair for part in comm.allgather(mine) for pair in part), key=lambda pair: pair[0])
    return studies.Study(cfg, ran, {"map": [row for _, row in rows]})
