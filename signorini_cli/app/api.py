"""The Python API: `load` a config (a YAML file or a mapping) and `run` its study, for notebooks and
scripts. `run` writes no files unless asked; a callback sees each level's solution before it is let go."""
import contextlib
import copy
import dataclasses
from dataclasses import dataclass
from pathlib import Path

from mpi4py import MPI

from .. import config, studies
from ..config import loader, settings
from ..record import results
from ..studies import rate_map
from . import guard, maps


@dataclass
class Study:
    """A finished study: its config, what the study type returned (Levels, a Sweep or a Total), its main
    table as rows (dicts with the rates.csv columns) and, for refinement and signorini studies, its verdict."""
    config: config.Config
    result: object
    rows: list
    summary: object = None


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
        settings.set_path(raw, name.replace("__", "."), value)
    cfg = config.from_dict(raw, folder)
    return dataclasses.replace(cfg, text=config.yaml_dump(raw))


def run(cfg, on_level=None, comm=MPI.COMM_WORLD, write=False):
    """Run cfg's study on `comm` and return it as a Study. on_level(level, u_h), if given, is called after
    each solve of a refinement or signorini study (total_error: of its sub-studies; a map: of its points)
    with the Level and its solution u_h (a dolfinx Function; the mesh is u_h.function_space.mesh), before
    the study lets u_h go. write=True writes rates.csv, summary.csv, study.h5 in cfg.output_dir as `signorini
    run` does, holding the folder's lock as it does (a map: as `signorini run --force` does)."""
    def each(result):
        last = list(result)[-1:]  # a map's point calls it as it starts too
        if last and getattr(last[0], "solution", None) is not None:
            on_level(last[0], last[0].solution)

    kind = studies.of(cfg.study_type)
    if kind.POINTS:
        return _run_map(cfg, (lambda point: each(point.levels)) if on_level else None, comm, write)
    with guard.FolderLock(cfg.output_dir, comm) if write else contextlib.nullcontext():
        result = studies.run_study(cfg, on_level=each if on_level else None, comm=comm)
        summary = kind.summary(cfg, result)
        if write:
            rows = results.write(cfg, result, comm, status=guard.status(cfg, result))
        else:
            rows = results.main_rows(kind.tables(cfg, result))
    return Study(cfg, result, rows, summary)


def _run_map(cfg, on_point, comm, write):
    """A map's Study: the Points this group of ranks ran, and map.csv's rows of every point."""
    if write:
        ran = maps.run(cfg, force=True, quiet=True, comm=comm, on_level=on_point)
    else:
        ran = studies.run_study(cfg, on_level=on_point, comm=comm)
    mine = [(p.index, rate_map.row(p.cfg, p.values, p.levels, maps.status_of(p), cfg.map.varied))
            for p in ran if p.comm.rank == 0]
    rows = sorted((pair for part in comm.allgather(mine) for pair in part), key=lambda pair: pair[0])
    return Study(cfg, ran, [row for _, row in rows])
