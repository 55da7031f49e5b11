"""The Python API: `load` a config (a YAML file or a mapping) and `run` its study, for notebooks and
scripts. `run` writes no files unless asked; a callback sees each level's solution before it is let go."""
import copy
import dataclasses
from pathlib import Path

from mpi4py import MPI

from .. import config, studies
from ..config import loader, reading
from . import guard


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
    if given, is called after each solve of a refinement or signorini study (total_error: of its sub-studies)
    with the Level and its solution u_h (a dolfinx Function; the mesh is u_h.function_space.mesh), before the
    study lets u_h go. write=True keeps rates.csv, summary.csv, study.h5 and status.txt in cfg.output_dir
    current after every solve, as `signorini run` does (its tables and figures are the command's)."""
    def each(study):
        if write:
            watch.level_done(study)
        last = list(study.result)[-1] if study.solves else None
        if on_level is not None and getattr(last, "solution", None) is not None:
            on_level(last, last.solution)

    if not write:
        return studies.run(cfg, each if on_level else None, comm)
    with guard.Watch(cfg, (), comm) as watch:
        return studies.run(cfg, each, comm)
