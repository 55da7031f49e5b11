"""Resuming a study: its finished levels read back from study.h5, when the config is unchanged or only
appends levels to the mesh's list."""
import json

from .. import config
from ..config import ConfigError
from ..solve import solver
from ..studies.level import Level
from . import results

# row columns that Level's own fields and Outcome produce (results.table); any other is Level.extra
OWN_COLUMNS = (set(results.SPEC_COLUMNS) | set(results.EXTRA_COLUMNS) | {"cumulative_time_s"}
               | {f"rate_{norm}" for norm in results.NORMS})


def finished_levels(cfg, comm):
    """The levels of `cfg` already in its study.h5, read on rank 0 and broadcast; [] when there is no
    study.h5. ConfigError on every rank when they cannot be continued (another config, unreadable)."""
    found = None
    if comm.rank == 0:
        try:
            found = ("levels", read_levels(cfg))
        except ConfigError as err:
            found = ("error", (err.path, err.message))
    kind, value = comm.bcast(found, root=0)
    if kind == "error":
        raise ConfigError(*value)
    return value


def read_levels(cfg):
    """The Level records in cfg.output_dir/study.h5, after checking it was written for this config."""
    import h5py
    folder = cfg.output_dir
    path = folder / "study.h5"
    if not path.exists():
        if (folder / "rates.csv").exists():
            raise ConfigError("--resume", f"{folder} has rates.csv but no study.h5 to resume from; "
                                          "use --force to start over")
        return []
    try:
        with h5py.File(path, "r") as h5:
            check_same_config(cfg, h5.attrs, path)
            columns = [str(c) for c in h5["table"].attrs.get("columns", [])]
            return [_level(h5[name], columns) for name in sorted(h5) if name.startswith("level_")]
    except (OSError, KeyError) as err:
        raise ConfigError("--resume", f"cannot read {path}: {err}; use --force to start over") from None


def check_same_config(cfg, attrs, path):
    """ConfigError unless study.h5's config hash is cfg's; the message names the keys that changed."""
    stored = attrs.get("config_hash")
    if stored is None:
        raise ConfigError("--resume", f"{path} has no config hash (written before --resume existed); "
                                      "use --force to start over")
    if stored != config.fingerprint(cfg):
        before = json.loads(attrs.get("config_canonical", "{}"))
        now = json.loads(json.dumps(config.canonical(cfg), sort_keys=True, default=str))
        if extends(before, now, cfg.mesh.level_key):
            return
        raise ConfigError("--resume", f"the config changed since {path} was written "
                                      f"({differences(before, now)}); use --force to start over")


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
    for key, value in tree.items():
        if isinstance(value, dict):
            flat.update(_flat(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = value
    return flat


def _level(group, columns):
    """One Level back from its group level_NN: the row as attributes, the residual history."""
    a = group.attrs
    outcome = solver.Outcome(converged=bool(a["converged"]), reason=str(a["reason"]),
                             newton_its=int(a["newton_its"]), linear_its=int(a["linear_its"]),
                             residuals=tuple(float(r) for r in group["residuals"][()]))
    errors = {name[len("measured_"):]: float(a[name]) for name in a if name.startswith("measured_")}
    row = {c: _plain(a[c]) if c in a else None for c in columns if c not in OWN_COLUMNS}
    extra = {c: v for c, v in row.items() if not results.is_timing(c) or c == "reference_time_s"}
    timings = {c: v for c, v in row.items() if c not in extra}
    return Level(int(a["level"]), int(a["N"]), float(a["h"]), int(a["dofs"]), float(a["epsilon"]),
                 outcome, errors, float(a["time_s"]), extra, timings=timings)


def _plain(value):
    """numpy scalars from h5py as Python values (the CSV writes true/false and ints as before)."""
    return value.item() if hasattr(value, "item") else value
