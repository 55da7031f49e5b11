"""The ε-sweep's config (study_type: epsilon_sweep, docs/limit.md): on each mesh, the compliance solutions
for decreasing ε against the Signorini VI's."""
from . import limit
from . import validators as check
from .schema import ConfigError, Limit

NAME = "epsilon_sweep"
DOC = ""  # how the reference and `signorini init` describe it beside its name
POINTS = False
VI = True
LIMIT_ERROR = False
GEOMETRY = False
FIELDS = False
DEGREES = (1,)
UNUSED = {"alpha": " (give the α values as limit.alpha)", "epsilon": " (the ε values are limit.epsilon)",
          "verification": "", "expect": ""}
LIMIT = (("epsilon",), ())  # the limit block's own keys: required, optional
SECTION = None


def check_config(cfg, raw):
    """Rules across sections: none beyond the generic ones."""
    return cfg


def parse_limit(raw, path, cfg):
    s, alpha, fit_last = limit.block(raw, path, NAME, *LIMIT, cfg.dimension, cfg.outside_theory)
    return Limit(alpha=alpha, epsilon=_epsilons(raw["epsilon"], s.at("epsilon")), fit_last=fit_last)


def _epsilons(raw, path):
    """The ε of a sweep, decreasing: a list, or a geometric range {start, stop, count}."""
    if isinstance(raw, dict):
        check.keys(raw, path, required=("start", "stop", "count"))
        start = check.number(raw["start"], f"{path}.start", positive=True)
        stop = check.number(raw["stop"], f"{path}.stop", positive=True)
        count = check.integer(raw["count"], f"{path}.count", low=2)
        if stop >= start:
            raise ConfigError(path, f"start must be larger than stop (ε decreases), got {start:g} and {stop:g}")
        return tuple(start * (stop / start) ** (k / (count - 1)) for k in range(count))
    values = check.numbers(raw, path, positive=True)
    if len(values) < 2 or any(b >= a for a, b in zip(values, values[1:])):
        raise ConfigError(path, f"must be at least two decreasing values (each ε starts from the previous "
                                f"solution), got {list(values)}")
    return values
