"""The problems by PDE: a study reaches its function space, forms, boundary condition and errors only
through the module problem_of(cfg) returns, so a new PDE is one new module here."""
import contextlib
import weakref

from . import compliance, elastic_vi, elasticity, posed, vi

# cfg.problem.pde -> the compliance problem's module, and the module of its ε → 0 limit (the Signorini VI)
PROBLEMS = {"poisson": compliance, "elasticity": elasticity}
LIMITS = {"poisson": vi, "elasticity": elastic_vi}


def problem_of(cfg, limit=False):
    """The module of cfg's problem (space, forms, dirichlet_condition, errors); with `limit`, the module
    of its Signorini variational inequality (paper eq. (8))."""
    return (LIMITS if limit else PROBLEMS)[cfg.problem.pde]


# the checks a problem's data pass before its first solve (problems/posed.py: the scalar problem's)
POSED = {"poisson": posed.check}


_passed = None  # within checked_once(): {(id(mesh), data): weak reference to the mesh they passed on}


@contextlib.contextmanager
def checked_once():
    """Within: a problem's data are checked once on each level's mesh (a map's points share their meshes
    and, but for ε and α, their data)."""
    global _passed
    _passed = {}
    try:
        yield
    finally:
        _passed = None


def check_posed(cfg, domain, u_exact, eps_value):
    """ConfigError (on every rank) when the level's problem is not posed right, where its PDE has a check."""
    if cfg.problem.pde not in POSED:
        return
    key = (id(domain.mesh), _data(cfg.problem, eps_value))
    if _passed is not None and key in _passed and _passed[key]() is domain.mesh:
        return
    POSED[cfg.problem.pde](cfg, domain, u_exact, eps_value)
    if _passed is not None:
        for gone in [k for k, mesh in _passed.items() if mesh() is None]:
            del _passed[gone]
        _passed[key] = weakref.ref(domain.mesh)


def _data(problem, eps_value):
    """What the check of a problem's data depends on: their texts, and ε where they use it."""
    texts = [e.text if e is not None else None for e in (problem.exact, problem.f, problem.g)]
    uses_eps = any(e is not None and "eps" in e.names for e in (problem.exact, problem.f, problem.g))
    defined = tuple((name, e.text) for name, e in problem.define)
    return repr((texts, defined, problem.exact_solves, eps_value if uses_eps else None))
