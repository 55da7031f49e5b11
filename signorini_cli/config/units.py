"""What the config knows of each problem (problem.pde), contact method (problem.method) and study type
(study_type): each is one light module of this folder with its keys, its section and its rules; a new one is
its module and one line below. The config layer asks these modules and never compares their names.

Each module has NAME and DOC (a few words beside its name in the reference, or "").
A problem module has KEYS (the problem keys it takes besides pde and method), SECTION (a schema.UnitSection
of its own, or None; then also section(raw, path)), DEGREES (its element degrees), VECTOR (u has one component
per coordinate), VI (it has a Signorini variational inequality; then also check_vi(problem, study_unit)),
problem(raw, path, dim) -> schema.Problem and check_config(cfg, raw) -> cfg (its rules across sections).
A method module has PDES (the problems it is built for), SECTION (and section(raw, path)), UNUSED (top-level
keys it refuses, e.g. the penalty's epsilon: key -> hint; to_dict leaves them out) and
check_config(cfg, raw) -> cfg.
A study type module has POINTS (a map of studies, config/map.py), VI (it solves the problem's VI),
LIMIT_ERROR (it measures u_S − u_h against a manufactured Signorini solution),
GEOMETRY (it runs on gmsh and .msh meshes), FIELDS (it writes output.fields), DEGREES, UNUSED (top-level keys
it refuses: key -> hint), LIMIT ((required, optional) keys of its limit block, or None; then also
parse_limit(raw, path, cfg)), SECTION and check_config(cfg, raw) -> cfg."""
from . import method_nitsche, method_penalty, pde_elasticity, pde_poisson
from .study_types import STUDY_TYPES

PDES = {unit.NAME: unit for unit in (pde_poisson, pde_elasticity)}
METHODS = {unit.NAME: unit for unit in (method_penalty, method_nitsche)}
# the key choosing a unit of each kind, and its units
KINDS = {"problem.pde": PDES, "problem.method": METHODS, "study_type": STUDY_TYPES}


def chosen(cfg):
    """The problem, method and study type a config chooses."""
    return (PDES[cfg.problem.pde], METHODS[cfg.problem.method], STUDY_TYPES[cfg.study_type])


def sections():
    """(key, UnitSection, the sentence saying when it applies) of every registered section, in order."""
    return [(unit.SECTION.key, unit.SECTION, f"only with {kind}: {name}")
            for kind, units in KINDS.items() for name, unit in units.items() if unit.SECTION is not None]


def takers(units, has):
    """The names of the units for which `has(unit)` holds, as "a or b"."""
    return " or ".join(name for name, unit in units.items() if has(unit))
