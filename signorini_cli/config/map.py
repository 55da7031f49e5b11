"""The rate map's config section (study_type: map): dotted config keys with lists of values; every
combination, and every explicit point, is one refinement study, validated here before any solve."""
import copy
import dataclasses
import itertools
import math
from pathlib import Path

from . import reading, rendering, settings
from . import validators as check
from .schema import ConfigError, Map, default, keys_of

BLOCK = "map"  # the key of the map's own block
# points of one map at most: each is a refinement study, and checking one takes about a millisecond
MAX_POINTS = 1000
# what names, places or makes the map itself: a point takes these from the map
FIXED = ("study", "study_type", BLOCK, "output", "description")


def parse(raw, base, folder):
    """The `map` block of the config mapping `raw` (whose other keys validated as `base`), with every
    point's config: a key or value a single study refuses is a ConfigError naming key, value and point."""
    block = raw.get(BLOCK)
    if block is None:
        raise ConfigError(BLOCK, "missing: study_type map needs a map block (map.grid)")
    check.keys(block, BLOCK, optional=keys_of(Map))
    grid = _grid(block.get("grid", {}), "map.grid")
    listed = _list(block.get("points", list(default(Map, "points"))), "map.points")
    points = tuple(_point(p, f"map.points[{i}]") for i, p in enumerate(listed))
    if not grid and not points:
        raise ConfigError("map.grid", "give at least one dotted key with its list of values")
    count = math.prod(len(values) for values in grid.values()) * bool(grid) + len(points)
    if count > MAX_POINTS:
        raise ConfigError("map.grid", f"{count} points, more than a map's {MAX_POINTS}: split it into maps "
                                      "of fewer values")
    values = tuple(dict(zip(grid, combo)) for combo in itertools.product(*grid.values())) + points
    wheres = ["map.grid.{key}"] * (len(values) - len(points)) + [f"map.points[{i}].{{key}}" for i in range(len(points))]
    studies = tuple(point_config(raw, k, point, base.output_dir / "points", folder, where)
                    for k, (point, where) in enumerate(zip(values, wheres)))
    s = check.Section(block, BLOCK, Map)
    return Map(grid, points, s.integer("jobs", low=1), s.integer("ranks_per_point", low=1), studies, values)


def _grid(raw, path):
    if not isinstance(raw, dict):
        raise ConfigError(path, "must be a mapping of dotted config keys to lists of values, got "
                                f"{check.show(raw)}")
    grid = {}
    for key, values in _dotted(raw):
        _check_key(key, f"{path}.{key}")
        _check_once(key, grid, path)
        grid[key] = _list(values, f"{path}.{key}")
        if not grid[key]:
            raise ConfigError(f"{path}.{key}", "must be a non-empty list of values")
    return grid


def _dotted(raw, prefix=""):
    """(dotted key, values) pairs; nested mappings (from `--set map.grid.epsilon.theta=[...]`) joined by dots."""
    for key, value in raw.items():
        if isinstance(value, dict) and isinstance(key, str):
            yield from _dotted(value, f"{prefix}{key}.")
        else:
            yield f"{prefix}{key}", value


def _point(raw, path):
    if not isinstance(raw, dict) or not raw:
        raise ConfigError(path, f"must be a mapping of dotted config keys to values, got {check.show(raw)}")
    for key in raw:
        _check_key(key, f"{path}.{key}")
    keys = [key for key, _ in _dotted(raw)]
    for i, key in enumerate(keys):
        _check_once(key, keys[:i], path)
    return dict(raw)


def _check_once(key, given, path):
    """A key the map sets once: `epsilon.theta` and `epsilon: {theta: ...}` (or `epsilon: ...`) both
    set epsilon.theta, and one would silently replace the other."""
    for other in given:
        if other == key or other.startswith(f"{key}.") or key.startswith(f"{other}."):
            twice = "is given twice" if other == key else f"and {other} are both given"
            raise ConfigError(f"{path}.{key}", f"{key} {twice}: a dotted key and a nested mapping set the same "
                                               "key, one would replace the other")


def _list(raw, path):
    if not isinstance(raw, list):
        raise ConfigError(path, f"must be a list, got {check.show(raw)}")
    return list(raw)


def _check_key(key, path):
    if not isinstance(key, str) or not key.strip():
        raise ConfigError(path, "must be a dotted config key such as epsilon.theta")
    if key.split(".")[0] in FIXED:
        raise ConfigError(path, f"cannot vary: the map gives its points {', '.join(FIXED)}")


def point_config(raw, k, point, folder, files, where):
    """Point k's Config: the map's config with the point's values, named k, written into folder/k/."""
    study = {name: copy.deepcopy(value) for name, value in raw.items() if name not in (BLOCK, "study_type")}
    try:
        for key, value in point.items():
            reading.set_path(study, key, copy.deepcopy(value))
        study.update(study=str(k), output=dict(study.get("output") or {}, dir=str(folder)))
        cfg = settings.validate(study, files)
    except ConfigError as err:
        key = next((key for key in point if err.path.startswith(key)), next(iter(point)))
        raise ConfigError(where.format(key=key), f"point {k} ({describe(point)}): {err}") from None
    text = reading.yaml_dump(rendering.to_dict(cfg))
    return dataclasses.replace(cfg, text=text)


def describe(point):
    """key=value, ... of a point (one line)."""
    return ", ".join(f"{key}={_value(value)}" for key, value in point.items())


def _value(value):
    return f"{value:g}" if isinstance(value, float) else str(value)


def chunk(text, count):
    """The point indices of `--points 0-49,60` (inclusive ranges), checked against the map's count."""
    chosen = set()
    for part in str(text).split(","):
        first, dash, last = part.strip().partition("-")
        try:
            lo, hi = int(first), int(last if dash else first)  # "2-" and "" name no point
        except ValueError:
            raise ConfigError("--points", f"expected ranges such as 0-49,60, got {text!r}") from None
        if not 0 <= lo <= hi < count:
            raise ConfigError("--points", f"{part.strip()} is not within the map's points 0-{count - 1}")
        chosen.update(range(lo, hi + 1))
    return sorted(chosen)


def folder_of(cfg):
    """Where a map's points are written: <map folder>/points/."""
    return Path(cfg.output_dir) / "points"
