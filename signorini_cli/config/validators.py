"""The generic checks every section's keys go through: known keys, numbers, integers, choices, expressions;
each error names the key's dotted path."""
import difflib
import math

from . import expressions
from .schema import ConfigError, default


class UnknownKey(ConfigError):
    """A key its section does not have; settings adds the did-you-mean, knowing every registered section."""

    def __init__(self, path, section, name, allowed):
        self.section, self.name, self.allowed = section, name, allowed
        super().__init__(path, f"unknown key in {section or 'config'}")


def keys(raw, path, required=(), optional=()):
    """Check a mapping has the required keys and no unknown ones."""
    if not isinstance(raw, dict):
        raise ConfigError(path, f"must be a mapping, got {show(raw)}")
    for name in raw:
        if name not in required and name not in optional:
            raise UnknownKey(join(path, name), path, name, tuple(required) + tuple(optional))
    for name in required:
        if name not in raw:
            raise ConfigError(join(path, name), "missing required key")


def join(path, key):
    return f"{path}.{key}" if path else str(key)


def show(value):
    return f"{type(value).__name__} {value!r}" if not isinstance(value, (dict, list)) else type(value).__name__


def number(value, path, low=None, positive=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(path, f"must be a number, got {show(value)}")
    value = float(value)
    if not math.isfinite(value):
        raise ConfigError(path, f"must be finite, got {value}")
    if positive and value <= 0:
        raise ConfigError(path, f"must be > 0, got {value:g}")
    if low is not None and value < low:
        raise ConfigError(path, f"must be >= {low:g}, got {value:g}")
    return value


def numbers(raw, path, low=None, positive=False):
    """A non-empty list of numbers; a single number is a list of one."""
    values = raw if isinstance(raw, list) else [raw]
    if not values:
        raise ConfigError(path, "must be a non-empty list of numbers")
    return tuple(number(v, f"{path}[{i}]" if isinstance(raw, list) else path, low=low, positive=positive)
                 for i, v in enumerate(values))


def integer(value, path, low=None, high=None):
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError(path, f"must be an integer, got {show(value)}")
    if low is not None and value < low:
        raise ConfigError(path, f"must be >= {low}, got {value}")
    if high is not None and value > high:
        raise ConfigError(path, f"must be <= {high}, got {value}")
    return value


def boolean(value, path):
    if not isinstance(value, bool):
        raise ConfigError(path, f"must be true or false, got {show(value)}")
    return value


def string(value, path, empty=False):
    if not isinstance(value, str) or (not empty and not value.strip()):
        raise ConfigError(path, f"must be a non-empty string, got {show(value)}")
    return value


def choice(value, path, choices):
    if value not in choices:
        close = difflib.get_close_matches(str(value).replace("-", "_").lower(), [str(c) for c in choices],
                                          n=1, cutoff=0.8)  # 0.8: unit_disk is not unit_square
        hint = f" (did you mean {close[0]!r}?)" if close else ""  # theta-h: theta_h
        raise ConfigError(path, f"{value!r} is not one of {', '.join(map(str, choices))}{hint}")
    return value


def expression(text, path, variables, defined=None):
    try:
        return expressions.parse(text, variables, defined)
    except expressions.ExpressionError as err:
        raise ConfigError(path, str(err)) from None


class Section:
    """One mapping of the config read against its dataclass: an absent key takes the field's default
    (defaults are written there only), an error names the key's dotted path."""

    def __init__(self, raw, path, cls):
        self.raw, self.path, self.cls = raw, path, cls

    def get(self, name):
        return self.raw.get(name, default(self.cls, name))

    def at(self, name):
        return join(self.path, name)

    def number(self, name, **limits):
        return number(self.get(name), self.at(name), **limits)

    def integer(self, name, **limits):
        return integer(self.get(name), self.at(name), **limits)

    def boolean(self, name):
        return boolean(self.get(name), self.at(name))

    def choice(self, name, choices):
        return choice(self.get(name), self.at(name), choices)

    def string(self, name, empty=False):
        return string(self.get(name), self.at(name), empty=empty)

    def section(self, name):
        """A sub-mapping's raw value ({} when absent: every key at its default)."""
        return self.raw.get(name, {})
