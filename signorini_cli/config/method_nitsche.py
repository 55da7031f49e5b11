"""Nitsche's method's config (problem.method: nitsche): the Signorini problem itself, discretised consistently
with γ = γ0 h_K (problems/nitsche.py); its section `nitsche: {theta, gamma0}`. It has no ε and no α: the
penalty's keys are refused, and so are data and measures that only the compliance model has."""
from dataclasses import dataclass

from . import pde_poisson
from .study_types import STUDY_TYPES
from . import validators as check
from .schema import ConfigError, UnitSection, key, keys_of

NAME = "nitsche"
DOC = "Nitsche's method, section nitsche"  # beside its name in the reference and `signorini init`
PDES = ("poisson",)  # scalar P1 (its Γ_C term is integrated exactly for P1)
# the compliance model's keys: refused, and left out of the resolved config
UNUSED = {key: f" ({NAME} has no ε and no α)" for key in ("alpha", "epsilon", "positive_part", "contact_quadrature")}
THETAS = (1.0, 0.0, -1.0)  # symmetric, incomplete, skew-symmetric
MEASURES = ("L2_gc", "penetration", "contact_measure", "contact_force", "diff")  # those it has (no ε, no α)


@dataclass(frozen=True)
class Nitsche:
    """θ and γ0 of Nitsche's method, γ = γ0 h_K."""
    theta: float = key(1.0, "1 (symmetric) | 0 (incomplete) | -1 (skew-symmetric)")
    gamma0: float = key(0.1, "γ = γ0 h_K (h_K: the diameter of the cell owning the Γ_C facet), > 0; θ = 1 and 0 "
                             "are proven for γ0 small enough")


SECTION = UnitSection("nitsche", Nitsche, "Nitsche's method: {theta, gamma0}")


def section(raw, path):
    """nitsche: {theta: 1 | 0 | -1, gamma0 > 0}."""
    check.keys(raw, path, optional=keys_of(Nitsche))
    s = check.Section(raw, path, Nitsche)
    theta = s.number("theta")
    if theta not in THETAS:
        raise ConfigError(s.at("theta"), f"must be 1, 0 or -1, got {theta:g}")
    return Nitsche(theta, s.number("gamma0", positive=True))


def check_config(cfg, raw):
    """The study solves the problem itself (not its VI), P1, with a Signorini solution or data f alone, no
    ε anywhere; θ ≠ 1 makes the Jacobian non-symmetric, which CG cannot solve: a direct linear solver."""
    study = STUDY_TYPES[cfg.study_type]
    if study.VI:
        raise ConfigError("problem.method", f"{NAME} is solved by refinement studies and maps; study_type "
                                            f"{cfg.study_type} solves the Signorini VI and the penalty model")
    _check_problem(cfg.problem)
    if cfg.element.degree != 1:
        raise ConfigError("element.degree", f"{NAME} is built for P1 (its Γ_C term integrated exactly), "
                                            f"got {cfg.element.degree}")
    if cfg.nitsche.theta != 1 and cfg.solver.linear != "direct":
        raise ConfigError("solver.linear", f"nitsche.theta {cfg.nitsche.theta:g} makes the Jacobian "
                                           "non-symmetric, which CG cannot solve: set solver.linear: direct")
    _check_verification(cfg.verification, raw.get("verification", {}))
    return cfg


def _check_problem(problem):
    if problem.exact is not None and not pde_poisson.EXACT_SOLVES[problem.exact_solves].signorini:
        raise ConfigError("problem.exact_solves", f"{NAME} discretises the Signorini problem: its manufactured "
                                                  "solution is one (set exact_solves: signorini)")
    if problem.g is not None:
        raise ConfigError("problem.g", f"the compliance model's data: {NAME} solves the Signorini problem, g = 0")
    for name, expression in (("exact", problem.exact), ("f", problem.f)):
        if expression is not None and "eps" in expression.names:
            raise ConfigError(f"problem.{name}", f"{NAME} has no ε: {expression.text} uses eps")


def _check_verification(verification, given):
    for i, m in enumerate(verification.measures or ()):
        if m not in MEASURES:
            raise ConfigError(f"verification.measures[{i}]", f"{NAME} measures {', '.join(MEASURES)}, not {m} "
                                                             "(a term of the compliance model)")
    if "reference_epsilon" in given:
        raise ConfigError("verification.reference_epsilon", f"only meaningful with an ε ({NAME} has none)")
