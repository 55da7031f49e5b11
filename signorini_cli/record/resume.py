"""Resuming a study: its finished levels read back from study.h5 by their index, when the config is
unchanged (or only appends levels to the mesh's list) and every level up to the last is there whole."""
import json
import math
from dataclasses import dataclass

import numpy as np

from .. import config, studies
from ..config import ConfigError
from ..solve import solver
from ..studies.level import EXTRA_COLUMNS, NORMS, LEADING_COLUMNS, Level
from ..system import files
from . import h5, results

# row columns that Level's own fields and Outcome produce (level.rate_table); any other is Level.extra
OWN_COLUMNS = (set(LEADING_COLUMNS) | set(EXTRA_COLUMNS) | {"cumulative_time_s"} | {f"rate_{norm}" for norm in NORMS})
FORCE = "use --force to start over"


SOLUTION = "solution.h5"  # the last converged level's u_h, beside study.h5: where an extended study goes on from


@dataclass(frozen=True)
class Stored:
    """A level's u_h as its dof points (nodes, 3) and values (nodes, bs), in no rank's order: a resumed
    study matches them to its own dofs by their points (studies.refinement)."""
    index: int
    points: np.ndarray
    values: np.ndarray


def finished_levels(cfg, comm):
    """The levels of `cfg` already in its study.h5, read on rank 0 and broadcast, the last converged one
    with its stored u_h (Level.solution, a Stored) when solution.h5 holds it; [] when there is no
    study.h5. ConfigError on every rank when they cannot be continued (another config, unreadable)."""
    levels = on_rank_zero(comm, lambda: read_levels(cfg))
    converged = [lv for lv in levels if lv.outcome.converged]
    if converged:
        converged[-1].solution = comm.bcast(read_solution(cfg, converged[-1].index) if comm.rank == 0 else None)
    return levels


def keep_solution(cfg, levels, comm):
    """Write the newest level's u_h to solution.h5 (rank 0, atomically) when it converged: what a resumed
    or extended study needs to go on without solving its finished levels again. Collective."""
    if not isinstance(levels, list) or not levels or not studies.of(cfg.study_type).RESUMABLE:
        return
    level = levels[-1]
    if level.solution is None or isinstance(level.solution, Stored) or not level.outcome.converged:
        return
    V = level.solution.function_space
    owned, bs = V.dofmap.index_map.size_local, V.dofmap.index_map_bs
    parts = comm.gather((V.tabulate_dof_coordinates()[:owned], level.solution.x.array.reshape(-1, bs)[:owned]))
    if comm.rank == 0:
        points, values = (np.concatenate([part[k] for part in parts]) for k in (0, 1))
        data = h5.solution_bytes(level.index, points, values)
        files.replace(cfg.output_dir / SOLUTION, lambda path: path.write_bytes(data))


def read_solution(cfg, index):
    """The Stored u_h of level `index` in solution.h5, or None (no file, another level, unreadable)."""
    path = cfg.output_dir / SOLUTION
    found = h5.read_solution(path) if path.exists() else None
    return Stored(*found) if found is not None and found[0] == index else None


def on_rank_zero(comm, find):
    """find() on rank 0 (which reads the files), its result, or its ConfigError, on every rank."""
    found = None
    if comm.rank == 0:
        try:
            found = ("ok", find())
        except ConfigError as err:
            found = ("error", (err.path, err.message))
    kind, value = comm.bcast(found, root=0)
    if kind == "error":
        raise ConfigError(*value)
    return value


def read_levels(cfg):
    """The Level records in cfg.output_dir/study.h5, in index order, after checking it was written for
    this config and holds levels 0 .. k-1 each whole (a gap or a damaged level is refused, never solved again)."""
    if not studies.of(cfg.study_type).RESUMABLE:
        raise ConfigError("--resume", f"study_type {cfg.study_type} runs from the start; {FORCE}")
    folder = cfg.output_dir
    path = folder / h5.NAME
    if not path.exists():
        if (folder / "rates.csv").exists():
            raise ConfigError("--resume", f"{folder} has rates.csv but no study.h5 to resume from; {FORCE}")
        return []
    try:
        record = h5.read(path)
    except h5.Damaged as err:
        raise ConfigError("--resume", f"{err}; {FORCE}") from None
    check_same_config(cfg, record.attrs, path)
    if record.main is None:
        raise ConfigError("--resume", f"{path} is damaged: no table group; {FORCE}")
    rows = record.tables[record.main]
    indices = sorted(record.levels)
    if indices != list(range(len(indices))) or len(rows) != len(indices):
        missing = sorted(set(range(max(indices + [len(rows) - 1]) + 1)) - set(indices))
        raise ConfigError("--resume", f"{path} is damaged: no group level_{missing[0]:02d} (it has "
                                      f"{len(indices)} level group(s), the table {len(rows)} row(s)); {FORCE}")
    columns = list(rows[0]) if rows else []
    return [_level(path, index, *record.levels[index], columns) for index in indices]


def check_same_config(cfg, attrs, path):
    """ConfigError unless study.h5's config hash is cfg's; the message names the keys that changed."""
    stored = attrs.get("config_hash")
    if stored is None:
        raise ConfigError("--resume", f"{path} has no config hash (written before --resume existed); {FORCE}")
    if stored != config.fingerprint(cfg):
        try:
            before = json.loads(attrs.get("config_canonical", "{}"))
        except (TypeError, ValueError):
            before = {}
        now = json.loads(json.dumps(config.canonical(cfg), sort_keys=True, default=str))
        if extends(before, now, cfg.mesh.level_key):
            return
        raise ConfigError("--resume", f"the config changed since {path} was written "
                                      f"({differences(before, now)}); {FORCE}")


def extends(before, now, key):
    """Whether `now` is the config `before` with levels appended to mesh.<key>: the finished levels solved
    the same problems, so the study goes on with the new ones."""
    old, new = before.get("mesh", {}).get(key), now.get("mesh", {}).get(key)
    if not isinstance(old, list) or not isinstance(new, list) or len(new) <= len(old) or new[:len(old)] != old:
        return False
    return dict(before, mesh=dict(before["mesh"], **{key: new})) == now


def differences(before, now):
    """'key.path: old -> new, ...' between two nested mappings (at most three named)."""
    before, now = _flat(before), _flat(now)
    changed = [f"{key}: {before.get(key)!r} -> {now.get(key)!r}"
               for key in sorted(set(before) | set(now)) if before.get(key) != now.get(key)]
    shown = ", ".join(changed[:3]) + (f" and {len(changed) - 3} more" if len(changed) > 3 else "")
    return shown or "config hash differs"


def _flat(tree, prefix=""):
    flat = {}
    for key, value in (tree.items() if isinstance(tree, dict) else ()):
        if isinstance(value, dict):
            flat.update(_flat(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = value
    return flat


# a level group's attributes Level needs, and the Python types they must have
LEVEL_TYPES = {"level": int, "N": int, "h": float, "dofs": int, "epsilon": float, "converged": bool,
               "reason": str, "newton_its": int, "linear_its": int, "time_s": float}


def _level(path, index, attrs, datasets, columns):
    """One Level back from its group level_NN: the row as attributes, the residual history; ConfigError
    naming the attribute that is missing or of the wrong type."""
    where = f"{path}: level_{index:02d}"
    a = {name: _typed(where, name, attrs.get(name), kind) for name, kind in LEVEL_TYPES.items()}
    if a["level"] != index:
        raise ConfigError("--resume", f"{where} says it is level {a['level']}; {FORCE}")
    try:
        residuals = tuple(float(r) for r in datasets["residuals"])
        errors = {name[len("measured_"):]: float(attrs[name]) for name in attrs if name.startswith("measured_")}
    except (KeyError, TypeError, ValueError) as err:
        raise ConfigError("--resume", f"{where} is damaged ({err}); {FORCE}") from None
    outcome = solver.Outcome(converged=a["converged"], reason=a["reason"], newton_its=a["newton_its"],
                             linear_its=a["linear_its"], residuals=residuals)
    row = {c: attrs.get(c) for c in columns if c not in OWN_COLUMNS}
    extra = {c: v for c, v in row.items() if not results.is_timing(c) or c == "reference_time_s"}
    timings = {c: v for c, v in row.items() if c not in extra}
    return Level(index, a["N"], a["h"], a["dofs"], a["epsilon"], outcome, errors, a["time_s"], extra,
                 timings=timings)


def _typed(where, name, value, kind):
    """value as `kind`, or ConfigError: a count must be a whole number, a flag true/false, h finite."""
    if value is None:
        raise ConfigError("--resume", f"{where} has no attribute {name}; {FORCE}")
    if kind is bool and isinstance(value, (bool, int)) and value in (0, 1):
        return bool(value)
    if kind is int and isinstance(value, (int, float)) and not isinstance(value, bool) \
            and math.isfinite(value) and float(value).is_integer():
        return int(value)
    if kind is float and isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
        return float(value)
    if kind is str and isinstance(value, str):
        return value
    wanted = {bool: "true or false", int: "a whole number", float: "a finite number", str: "text"}[kind]
    raise ConfigError("--resume", f"{where} attribute {name} is {value!r}, not {wanted}; {FORCE}")
