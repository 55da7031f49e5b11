"""The total-error study's config (study_type: total_error, docs/limit.md): u_S − u_h for ε = θ h^p, one
refinement study per (α, p)."""
from . import limit
from . import validators as check
from .schema import ConfigError, Limit

NAME = "total_error"
DOC = ""  # how the reference and `signorini init` describe it beside its name
POINTS = False
VI = True
LIMIT_ERROR = True  # it measures u_S − u_h: the problem needs a manufactured Signorini solution
GEOMETRY = False
FIELDS = True
DEGREES = (1,)
UNUSED = {"alpha": " (give the α values as limit.alpha)",
          "epsilon": " (ε = θ h^p from limit.theta and limit.exponent)",
          "expect": " (the sub-studies differ: no single rate to expect)"}
LIMIT = (("exponent",), ("theta",))  # the limit block's own keys: required, optional
SECTION = None


def check_config(cfg, raw):
    """It measures u_S − u_h: a manufactured u_S is needed."""
    if cfg.problem.exact is None:
        raise ConfigError("problem.exact", f"study_type {NAME} measures u_S − u_h: give u_S")
    return cfg


def parse_limit(raw, path, cfg):
    s, alpha, fit_last = limit.block(raw, path, NAME, *LIMIT, cfg.dimension, cfg.outside_theory)
    return Limit(alpha=alpha, theta=s.number("theta", positive=True),
                 exponent=check.numbers(raw["exponent"], s.at("exponent"), positive=True), fit_last=fit_last)
