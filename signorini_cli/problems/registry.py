"""The problems by PDE: a study reaches its function space, forms, boundary condition and errors only
through the module problem_of(cfg) returns, so a new PDE is one new module here."""
import contextlib
import dataclasses

from ..meshing import meshes
from . import compliance, elastic_vi, elasticity, element, posed, vi

# cfg.problem.pde -> the compliance problem's module, and the module of its ε → 0 limit (the Signorini VI)
PROBLEMS = {"poisson": compliance, "elasticity": elasticity}
LIMITS = {"poisson": vi, "elasticity": elastic_vi}


def problem_of(cfg, limit=False):
    """The module of cfg's problem (space, forms, dirichlet_condition, errors); with `limit`, the module
    of its Signorini variational inequality (paper eq. (8))."""
    return (LIMITS if limit else PROBLEMS)[cfg.problem.pde]


# the checks a problem's data pass before its first solve (problems/posed.py)
POSED = {"poisson": posed.check, "elasticity": posed.check_elastic}


_passed = None  # within checked_once(): (mesh family, data) -> the data's Profile on the family's coarsest mesh


@contextlib.contextmanager
def checked_once():
    """Within (a study, a map: re-entrant): a problem's data are checked at the cells' quadrature points, their
    load for settling and their Profile taken, once per mesh family, on its coarsest mesh (what a check at
    interior points can find there, it finds on any level); at the vertices and on Γ_C on every level (where
    a finer level's new vertices may meet a singularity)."""
    global _passed
    if _passed is not None:
        yield
        return
    _passed = {}
    try:
        yield
    finally:
        _passed = None


def check_posed(cfg, domain, u_exact, eps_value):
    """ConfigError (on every rank) when the level's problem is not posed right: every path that solves calls
    it before its first solve on a mesh (refinement levels, map points, the VI, ε-sweeps, total error).
    Returns the level's quadrature degrees (data, errors) the data need (posed.Profile.degrees)."""
    key = (_family(cfg), _data(cfg.problem, eps_value))
    coarsest = None
    if _passed is None or key not in _passed:  # the cells' checks: on the family's coarsest mesh
        first = cfg.mesh.levels[0]
        coarsest = domain if domain.n == first else meshes.build(cfg.mesh, cfg.contact, first, domain.mesh.comm)
    found = POSED[cfg.problem.pde](cfg, domain, u_exact, eps_value, coarsest=coarsest)
    if _passed is not None:
        found = _passed.setdefault(key, found)
    low = (compliance.QUADRATURE_DEGREE, element.error_degree(cfg.element.degree, domain.h, domain.mesh.topology.dim))
    return low if found is None else found.degrees(domain.h, *low)


def _family(cfg):
    """The mesh family a level belongs to: its mesh settings but the list of levels, and Γ_C."""
    return repr((dataclasses.replace(cfg.mesh, **{cfg.mesh.level_key: ()}), cfg.contact))


def _data(problem, eps_value):
    """What the check of a problem's data depends on: their texts, and ε where they use it."""
    given = _expressions(problem.exact) + [problem.f, problem.g, problem.gap]
    texts = [e.text if e is not None else None for e in given]
    uses_eps = any(e is not None and "eps" in e.names for e in given)
    defined = tuple((name, e.text) for name, e in problem.define)
    return repr((texts, defined, problem.exact_solves, eps_value if uses_eps else None))


def _expressions(exact):
    """The exact solution's expressions: one (scalar) or one per component (elasticity)."""
    return list(exact) if isinstance(exact, tuple) else [exact]
