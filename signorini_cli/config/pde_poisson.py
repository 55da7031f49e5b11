"""The scalar problem's config (pde: poisson): a manufactured solution `exact`, or data `f` (and `g`), with
named definitions; `exact` solves the compliance model or, with exact_solves: signorini, the Signorini problem."""
from dataclasses import dataclass

from . import expressions
from . import validators as check
from .schema import COORDINATES, ConfigError, Problem, default

NAME = "poisson"
DOC = "the scalar model"  # how the reference and `signorini init` describe it beside its name
KEYS = ("exact", "f", "g", "exact_solves", "define")  # the problem keys it takes (besides pde and method)
SECTION = None  # no section of its own
DEGREES = (1, 2)  # the element degrees it has
VECTOR = False  # u is scalar
VI = True  # it has a Signorini variational inequality (paper eq. (8)), which the ε → 0 studies solve


@dataclass(frozen=True)
class Solves:
    """What a manufactured `exact` solves: whether it may depend on eps, and whether it is a Signorini
    solution u_S (the ε → 0 studies need one)."""
    eps: bool
    signorini: bool


EXACT_SOLVES = {"compliance": Solves(eps=True, signorini=False), "signorini": Solves(eps=False, signorini=True)}


def problem(raw, path, dim):
    """exact, or f (and g), each an expression in x, y (z), eps and the names of define."""
    coords = COORDINATES[dim]
    defined = define(raw.get("define", {}), f"{path}.define", coords + ("eps",))
    exact, f, g = (check.expression(raw[k], f"{path}.{k}", coords + ("eps",), defined) if k in raw else None
                   for k in ("exact", "f", "g"))
    if exact is None and f is None:
        raise ConfigError(path, "give exact (a manufactured solution) or f (data only)")
    if exact is not None and (f is not None or g is not None):
        raise ConfigError(path, "exact determines f and g; give exact alone, or f (and g) alone")
    return Problem(exact, f, g, _exact_solves(raw, path, exact), tuple(defined.items()))


def define(raw, path, variables):
    """problem.define: {name: expression}, each checked like problem.exact (errors in a definition's
    text name it: problem.define.r)."""
    if not isinstance(raw, dict):
        raise ConfigError(path, "must be a mapping of name to expression, e.g. {r: \"sqrt(x**2 + y**2)\"}")
    try:
        return expressions.definitions(raw, variables)
    except expressions.DefinitionError as err:
        raise ConfigError(f"{path}.{err.name}", err.message) from None
    except expressions.ExpressionError as err:
        raise ConfigError(path, str(err)) from None


def _exact_solves(raw, path, exact):
    """Which problem `exact` solves: the compliance model (default) or the Signorini problem."""
    if "exact_solves" not in raw:
        return default(Problem, "exact_solves")
    solves = check.choice(raw["exact_solves"], f"{path}.exact_solves", tuple(EXACT_SOLVES))
    if exact is None and EXACT_SOLVES[solves].signorini:
        raise ConfigError(f"{path}.exact_solves", "only meaningful with problem.exact")
    if not EXACT_SOLVES[solves].eps and "eps" in exact.names:
        raise ConfigError(f"{path}.exact", "a Signorini solution cannot depend on eps")
    return solves


def check_config(cfg, raw):
    """Rules across sections: the hertz measure is elasticity's."""
    measures = cfg.verification.measures or ()
    if "hertz" in measures:
        raise ConfigError(f"verification.measures[{measures.index('hertz')}]", "hertz measures an elastic Hertz "
                                                                                "contact (pde: elasticity)")
    return cfg


def check_vi(problem, study):
    """The ε → 0 studies need the Signorini problem: f (and u_S on Γ_D), contact data g = 0."""
    if problem.exact is not None and not EXACT_SOLVES[problem.exact_solves].signorini:
        raise ConfigError("problem.exact_solves", f"study_type {study.NAME} needs a Signorini solution: "
                                                  "set exact_solves: signorini, or give f alone")
    if problem.g is not None:
        raise ConfigError("problem.g", f"study_type {study.NAME} needs g = 0: the ε → 0 limit of "
                                       "ε∂_n u + [u]_+^α = g is a Signorini problem only then")
