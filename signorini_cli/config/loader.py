"""Reading a config: a YAML file or text, with the command line's overrides and PETSc options, validated
into a Config (settings), a map's block and points included (map)."""
import dataclasses
import os
import stat
from pathlib import Path

from . import map as rate_map
from . import petsc_options as petsc
from . import units
from .reading import MAX_BYTES, apply_override, set_path, yaml_load
from .schema import ConfigError
from .settings import suggesting, validate


def load(path, overrides=(), options=()):
    """Read a YAML config file (a regular file of at most MAX_BYTES), apply `KEY=VALUE` overrides and
    the (name, value) PETSc `options` of the command line, validate. Relative mesh paths in the file
    are relative to the file's folder."""
    data = read_bounded(path)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        line = data.count(b"\n", 0, err.start) + 1
        raise ConfigError("", f"not a UTF-8 text file (byte 0x{data[err.start]:02x} on line {line})") from None
    return loads(text, overrides, folder=Path(path).resolve().parent, options=options)


def read_bounded(path):
    """The bytes of a regular file, refused at once when it is something else (a FIFO or a device
    would block or never end, a folder has no text) or longer than MAX_BYTES."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # a FIFO's open would wait for a writer
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise ConfigError("", "not a regular file (a config is read from a file, not a folder, "
                                  "FIFO or device)")
        if info.st_size > MAX_BYTES:
            raise ConfigError("", f"{info.st_size} bytes, more than a config's limit of {MAX_BYTES}")
        with os.fdopen(fd, "rb") as file:
            fd = None
            data = file.read(MAX_BYTES + 1)
    finally:
        if fd is not None:
            os.close(fd)
    if len(data) > MAX_BYTES:
        raise ConfigError("", f"more than a config's limit of {MAX_BYTES} bytes")
    return data


def loads(text, overrides=(), folder=None, options=()):
    """Validate YAML text (after overrides, then PETSc `options` joining solver.petsc_options, as
    strings) into a Config; relative mesh paths resolve against `folder` (the config file's)."""
    raw = yaml_load(text)
    if not isinstance(raw, dict):
        raise ConfigError("", "the config must be a YAML mapping of keys to values")
    for item in overrides:
        apply_override(raw, item)
    for name, value in options:  # the command line wins over the file, however either spells the option
        written = (raw.get("solver") or {}).get("petsc_options") if isinstance(raw.get("solver"), dict) else None
        if isinstance(written, dict):
            for key in [k for k in written if petsc.canonical(k) == petsc.canonical(name)]:
                del written[key]
        set_path(raw, f"solver.petsc_options.{name}", value)
    return dataclasses.replace(from_dict(raw, folder), text=text)


def from_dict(raw, folder=None):
    """Validate a raw mapping into a Config, a map's points each validated as a study of its own;
    relative mesh paths are relative to `folder` (None: the working directory), and stored resolved."""
    cfg = validate(raw, folder)
    if units.STUDY_TYPES[cfg.study_type].POINTS:
        with suggesting():
            cfg = dataclasses.replace(cfg, map=rate_map.parse(raw, cfg, folder))
    return cfg
