"""Linear elasticity's config (pde: elasticity, docs/elasticity.md): one expression per component of u,
the initial gap and the obstacle's normal, and its own section `material`."""
import dataclasses
import math
from dataclasses import dataclass

from . import validators as check
from .schema import COORDINATES, ConfigError, Problem, UnitSection, key, keys_of

NAME = "elasticity"
KEYS = ("exact", "gap", "normal", "define")  # the problem keys it takes (besides pde and method)
DEGREES = (1,)  # P1 only: its forms and Γ_C measures are built for piecewise linear u_h
VI = False  # no Signorini variational inequality: it runs refinement studies


@dataclass(frozen=True)
class Material:
    """Isotropic linear elasticity: Young's modulus and Poisson's ratio (plane strain in 2-D)."""
    E: float = key(1.0, "Young's modulus, > 0")
    nu: float = key(0.3, "Poisson's ratio, in (-1, 0.5)")


SECTION = UnitSection("material", Material, "elasticity: {E, nu}")
# what the physical problem (no problem.exact) measures: Γ_C quantities only
DATA_MEASURES = ("penetration", "contact_measure", "contact_force")


def problem(raw, path, dim):
    """problem.exact: one expression per component of u; gap g0 (an expression, default 0); normal."""
    exact = _components(raw["exact"], f"{path}.exact", dim) if "exact" in raw else None  # None: f = 0, ĝ = 0
    gap = check.expression(raw["gap"], f"{path}.gap", COORDINATES[dim]) if "gap" in raw else None
    normal = _normal(raw["normal"], f"{path}.normal", dim) if "normal" in raw else None
    return Problem(exact=exact, pde=NAME, gap=gap, normal=normal)


def _components(value, path, dim):
    """A list of d expressions in x, y (z), eps: one per component of u."""
    if not isinstance(value, list) or len(value) != dim:
        got = f"{len(value)} components" if isinstance(value, list) else check.show(value)
        raise ConfigError(path, f"must be a list of {dim} expressions (one per component of u in {dim}-D), got {got}")
    return tuple(check.expression(c, f"{path}[{i}]", COORDINATES[dim] + ("eps",)) for i, c in enumerate(value))


def _normal(value, path, dim):
    """A unit vector of d numbers (normalised here; zero is refused)."""
    if not isinstance(value, list) or len(value) != dim:
        raise ConfigError(path, f"must be a list of {dim} numbers, got {check.show(value)}")
    n = [check.number(v, f"{path}[{i}]") for i, v in enumerate(value)]
    norm = math.sqrt(sum(v * v for v in n))
    if norm == 0:
        raise ConfigError(path, "must not be zero")
    return tuple(v / norm for v in n)


def section(raw, path):
    """material: {E, nu} (E > 0, -1 < nu < 1/2: the Lamé λ, μ finite and positive)."""
    check.keys(raw, path, optional=keys_of(Material))
    s = check.Section(raw, path, Material)
    E, nu = s.number("E"), s.number("nu")
    if E <= 0:
        raise ConfigError(s.at("E"), f"must be > 0, got {E:g}")
    if not -1 < nu < 0.5:
        raise ConfigError(s.at("nu"), f"must be in (-1, 0.5) (λ and μ finite and positive), got {nu:g}")
    return Material(E, nu)


def check_config(cfg, raw):
    """The physical elastic problem (no problem.exact) measures Γ_C quantities only: no reference
    solution and no successive differences of vector fields; fields are written for the scalar problem."""
    if cfg.output.fields:
        raise ConfigError("output.fields", "written for the scalar problem only (pde: poisson)")
    if cfg.problem.exact is not None:
        return cfg
    v, given = cfg.verification, raw.get("verification", {})
    if given.get("reference_refinements") not in (None, 0):
        raise ConfigError("verification.reference_refinements", f"pde: {NAME} without problem.exact has no "
                                                                "reference solution: set 0")
    measures = v.measures if v.measures is not None else DATA_MEASURES
    for i, m in enumerate(measures):
        if m not in DATA_MEASURES:
            raise ConfigError(f"verification.measures[{i}]", f"pde: {NAME} without problem.exact measures "
                                                            f"{', '.join(DATA_MEASURES)}, not {m}")
    return dataclasses.replace(cfg, verification=dataclasses.replace(v, measures=measures, reference_refinements=0))
