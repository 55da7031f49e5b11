"""The Python API: `load` a config (a YAML file or a mapping) and `run` its study, for notebooks and
scripts. `run` writes no files unless asked; a callback sees each level's solution before it is let go."""
import copy
import dataclasses
import inspect
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from .. import config, studies
from ..config import loader, reading
from ..meshing import meshes
from ..problems import profile
from ..record import results
from ..report import tables
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


@dataclass(frozen=True)
class Scene:
    """What on_level(level, u_h, scene) sees of a level besides u_h: the boundary tags (a dolfinx MeshTags)
    with the markers of Γ_C and Γ_D, the measure ds_c on Γ_C, the exact solution (UFL; None for data-only
    scenes), the contact pressure p_h = ε^{-1}[w_h]_+^α as a P1 function (w_h = u_h, or u_h·n − g for
    elasticity; None for the Signorini problem, which has no ε) and the errors' quadrature degree."""
    facet_tags: object
    gamma_c: int
    gamma_d: int
    ds_c: object
    u_exact: object
    pressure: object
    error_degree: int = None  # the quadrature degree the level's errors were integrated with (None: by h)

    def __repr__(self):
        return f"Scene(Γ_C = tag {self.gamma_c}, Γ_D = tag {self.gamma_d}, exact: {self.u_exact is not None})"


def scene_of(cfg, level, u_h):
    """The Scene of a level while its mesh is there (level.scene: its Domain and forms)."""
    import ufl
    from dolfinx import fem
    domain, forms = level.scene
    ds_c = forms.ds_c if forms is not None else ufl.Measure("ds", domain.mesh, subdomain_data=domain.facet_tags)(
        meshes.CONTACT)
    pressure = None
    if forms is not None and level.eps > 0 and forms.gap is not None:
        pressure = profile.elastic_pressure(cfg, forms, level.eps)
    elif forms is not None and level.eps > 0:
        space = fem.FunctionSpace(domain.mesh, ("Lagrange", 1))
        pressure = fem.Function(space, name="pressure")
        pressure.interpolate(fem.Expression(ufl.max_value(u_h, 0) ** cfg.alpha / level.eps,
                                            space.element.interpolation_points()))
    return Scene(domain.facet_tags, meshes.CONTACT, meshes.DIRICHLET, ds_c, forms.u_exact if forms is not None
                 else None, pressure, domain.quadrature[1] if domain.quadrature else None)


@dataclass(frozen=True, repr=False)
class Result(studies.Study):
    """A finished study (studies.Study) for a notebook: its tables as columns, the finest level's u_h written
    for ParaView, the report's tables and figures, and a one-line repr. `finest`: (u_h, Scene) of the last
    converged level (None for study types without levels)."""
    finest: object = None

    def columns(self, table=None):
        """A table (default: the main one) as {column: numpy array} (None as nan); pandas.DataFrame(...) takes it."""
        rows = self.tables[table] if table is not None else self.rows
        return {key: np.array([np.nan if row.get(key) is None else row.get(key) for row in rows])
                for key in (rows[0] if rows else {})}

    def dataframe(self, table=None):
        """The table as a pandas DataFrame (pandas imported here: it is optional)."""
        import pandas
        return pandas.DataFrame(self.columns(table))

    def write_fields(self, path):
        """The finest level's u_h with the boundary tags (1 = Γ_C, 2 = Γ_D) for ParaView: XDMF for P1 (path
        ending .xdmf), else VTX (a .bp folder); the path."""
        from dolfinx import io
        if self.finest is None:
            raise ValueError("no level's solution to write: run(...) keeps the finest converged level's")
        u_h, scene = self.finest
        path, msh = Path(path), u_h.function_space.mesh
        if path.suffix == ".xdmf" and u_h.function_space.ufl_element().degree() == 1:
            with io.XDMFFile(msh.comm, str(path), "w") as xdmf:
                xdmf.write_mesh(msh)
                scene.facet_tags.name = "boundary"
                xdmf.write_meshtags(scene.facet_tags)
                xdmf.write_function(u_h)
        else:
            with io.VTXWriter(msh.comm, str(path.with_suffix(".bp")), [u_h]) as vtx:
                vtx.write(0.0)
            path = path.with_suffix(".bp")
        return path

    def report(self, folder=None, **options):
        """The tables and figures `signorini report` writes (options as tables.write: digits, columns, figure,
        plots), into `folder` (default: the study's output folder); the paths (rank 0 writes)."""
        cfg = self.config
        study = results.Study(cfg.study, cfg.output_dir, self.rows, study_type=cfg.study_type, tables=self.tables)
        if MPI.COMM_WORLD.rank != 0:
            return []
        return tables.write(study, cfg, folder=folder or cfg.output_dir, summary=self.summary, **options)

    def __repr__(self):
        rows = self.rows
        finest = f", finest N = {rows[-1].get('N')}" if rows else ""
        return (f"Result({self.config.study!r}: {self.config.study_type}, {len(rows)} rows{finest}, "
                f"converged: {self.converged}, tables: {', '.join(self.tables)})")


def run(cfg, on_level=None, comm=MPI.COMM_WORLD, write=False):
    """Run cfg's study on `comm` and return it as a Result (the runner of `signorini run`). on_level(level, u_h)
    or on_level(level, u_h, scene), if given, is called after each solve of a refinement or signorini study
    (total_error: of its sub-studies; a map: of its points) with the Level, its solution u_h (a dolfinx
    Function; the mesh is u_h.function_space.mesh) and its Scene (boundary tags, ds_c, exact solution, contact
    pressure), before the study lets them go. write=True keeps rates.csv, summary.csv, study.h5 and status.txt
    in cfg.output_dir current after every solve, as `signorini run` does (its tables and figures:
    Result.report), holding the folder's lock as it does; a map is written as `signorini run --force` writes it."""
    kept = []
    wants_scene = on_level is not None and len(inspect.signature(on_level).parameters) >= 3

    def each(study):
        if write:
            watch.level_done(study)
        last = list(study.result)[-1] if study.solves else None
        if getattr(last, "solution", None) is None or getattr(last, "scene", None) is None:
            return
        scene = scene_of(cfg, last, last.solution)
        if last.outcome.converged:
            kept[:] = [(last.solution, scene)]  # the finest converged level's, for write_fields
        if on_level is not None:
            on_level(*(last, last.solution, scene)[:3 if wants_scene else 2])

    if studies.of(cfg.study_type).POINTS:
        return _run_map(cfg, on_level, comm, write)
    if not write:
        return _result(studies.run(cfg, each, comm), kept)
    with guard.FolderLock(cfg.output_dir, comm), guard.Watch(cfg, (), comm) as watch:
        return _result(studies.run(cfg, each, comm), kept)


def _result(study, kept):
    """The Study as a Result holding the finest converged level's (u_h, Scene)."""
    fields = {f.name: getattr(study, f.name) for f in dataclasses.fields(study)}
    return Result(**fields, finest=kept[0] if kept else None)


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
    return _result(studies.Study(cfg, ran, {"map": [row for _, row in rows]}), [])
