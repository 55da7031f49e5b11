"""Linear elasticity's config (pde: elasticity, docs/elasticity.md): one expression per component of u,
the initial gap and the obstacle's normal, and its own section `material`."""
import dataclasses
import math
from dataclasses import dataclass

from . import pde_poisson
from . import validators as check
from .schema import COORDINATES, FACES, ConfigError, Problem, UnitSection, key, keys_of
from .study_types import STUDY_TYPES

NAME = "elasticity"
DOC = "docs/elasticity.md"  # how the reference and `signorini init` describe it beside its name
KEYS = ("exact", "gap", "normal", "define", "hertz_radius")  # the problem keys it takes (besides pde and method)
DEGREES = (1, 2)  # the element degrees it has
VECTOR = True  # u has d components: d dofs per node, d × d Jacobian blocks
VI = True  # its Signorini problem: u·n <= g0 as bounds on one component (problems/elastic_vi.py)


@dataclass(frozen=True)
class Material:
    """Isotropic linear elasticity: Young's modulus and Poisson's ratio (plane strain in 2-D)."""
    E: float = key(1.0, "Young's modulus, > 0")
    nu: float = key(0.3, "Poisson's ratio, in (-1, 0.5)")


SECTION = UnitSection("material", Material, "elasticity: {E, nu}")
# what the physical problem (no problem.exact) measures by default: Γ_C quantities and successive differences
# (with references: verification.reference_refinements)
DATA_MEASURES = ("penetration", "contact_measure", "contact_force", "diff")


def problem(raw, path, dim):
    """problem.exact: one expression per component of u; gap g0 (an expression, default 0); normal; the
    names of define in exact and gap, as in the scalar problem."""
    coords = COORDINATES[dim]
    defined = pde_poisson.define(raw.get("define", {}), f"{path}.define", coords + ("eps",))
    exact = _components(raw["exact"], f"{path}.exact", dim, defined) if "exact" in raw else None  # None: f = 0
    gap = check.expression(raw["gap"], f"{path}.gap", coords, defined) if "gap" in raw else None
    if gap is not None and "eps" in gap.names:
        raise ConfigError(f"{path}.gap", "the initial gap cannot depend on eps (a definition it uses does)")
    normal = _normal(raw["normal"], f"{path}.normal", dim) if "normal" in raw else None
    radius = check.number(raw["hertz_radius"], f"{path}.hertz_radius") if "hertz_radius" in raw else None
    if radius is not None and (exact is not None or radius <= 0):
        raise ConfigError(f"{path}.hertz_radius", "must be > 0" if radius <= 0 else "a Hertz contact is the "
                                                  "physical problem: give no exact solution")
    return Problem(exact=exact, define=tuple(defined.items()), pde=NAME, gap=gap, normal=normal,
                   hertz_radius=radius)


def _components(value, path, dim, defined):
    """A list of d expressions in x, y (z), eps: one per component of u."""
    if not isinstance(value, list) or len(value) != dim:
        got = f"{len(value)} components" if isinstance(value, list) else check.show(value)
        raise ConfigError(path, f"must be a list of {dim} expressions (one per component of u in {dim}-D), got {got}")
    return tuple(check.expression(c, f"{path}[{i}]", COORDINATES[dim] + ("eps",), defined)
                 for i, c in enumerate(value))


def _normal(value, path, dim):
    """A unit vector of d numbers (normalised here; zero is refused). Scaled by its largest entry first, so
    that squaring neither overflows ([1e200, 1e200]) nor underflows ([1e-200, 0])."""
    if not isinstance(value, list) or len(value) != dim:
        raise ConfigError(path, f"must be a list of {dim} numbers, got {check.show(value)}")
    n = [check.number(v, f"{path}[{i}]") for i, v in enumerate(value)]
    largest = max(abs(v) for v in n)
    if largest == 0:
        raise ConfigError(path, "must not be zero")
    n = [v / largest for v in n]
    norm = math.sqrt(sum(v * v for v in n))
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
    """The physical elastic problem (no problem.exact) is measured as the scalar data-only scenes are, against
    reference solutions on refined meshes and by successive differences (L2 and H1 of the vector field), with
    the Γ_C quantities (and Hertz's, with hertz_radius); the Signorini problem bounds u·n on the face's own
    normal."""
    _check_normal_of_vi(cfg)
    measures = cfg.verification.measures or ()
    if "hertz" in measures and cfg.problem.hertz_radius is None:
        raise ConfigError(f"verification.measures[{measures.index('hertz')}]", "hertz needs problem.hertz_radius")
    if cfg.problem.hertz_radius is not None and cfg.element.degree != 1:
        raise ConfigError("problem.hertz_radius", "measured on P1 (the contact set's edge where the linear w_h "
                                                  "changes sign): give element.degree 1")
    if cfg.problem.exact is not None:
        return cfg
    v = cfg.verification
    default = DATA_MEASURES + (("hertz",) if cfg.problem.hertz_radius is not None else ())
    measures = v.measures if v.measures is not None else default
    for i, m in enumerate(measures):
        if m not in DATA_MEASURES + ("hertz",):
            raise ConfigError(f"verification.measures[{i}]", f"pde: {NAME} without problem.exact measures "
                                                            f"{', '.join(DATA_MEASURES + ('hertz',))}, not {m} "
                                                            "(the Γ_C errors read a scalar trace)")
    return dataclasses.replace(cfg, verification=dataclasses.replace(v, measures=measures))


def check_vi(problem, study):
    """The Signorini problem of elasticity is the physical one (f = 0, driven by the gap): no manufactured
    solution, so no total error."""
    if study.LIMIT_ERROR:
        raise ConfigError("study_type", f"{study.NAME} measures u_S − u_h: pde: elasticity has no manufactured "
                                        "Signorini solution (signorini and epsilon_sweep run it)")
    if problem.exact is not None:
        raise ConfigError("problem.exact", f"study_type {study.NAME} with pde: elasticity solves the physical "
                                           "problem (f = 0, driven by problem.gap): give no exact solution")


def _check_normal_of_vi(cfg):
    """The VI bounds u·n = ±u_k on a face x_k = 0 or 1 of the built-in meshes (the study types that solve it
    run on nothing else): problem.normal, if given, must be that face's outward normal."""
    faces = FACES[cfg.dimension]  # a gmsh or file mesh's group: refused for these study types by the mesh check
    if not STUDY_TYPES[cfg.study_type].VI or cfg.problem.normal is None or cfg.contact not in faces:
        return
    i = FACES[cfg.dimension].index(cfg.contact)  # the faces x_k = 0, x_k = 1 in the order of the axes k
    own = tuple((1.0 if i % 2 else -1.0) if k == i // 2 else 0.0 for k in range(cfg.dimension))
    if cfg.problem.normal != own:
        raise ConfigError("problem.normal", f"study_type {cfg.study_type} bounds u·n on the face's own normal "
                                            f"{list(own)} (one component of u): leave normal out")
