"""The problems by PDE: a study reaches its function space, forms, boundary condition and errors only
through the module problem_of(cfg) returns, so a new PDE is one new module here."""
from . import compliance, elasticity, posed, vi

# cfg.problem.pde -> the compliance problem's module, and the module of its ε → 0 limit (the Signorini VI)
PROBLEMS = {"poisson": compliance, "elasticity": elasticity}
LIMITS = {"poisson": vi}


def problem_of(cfg, limit=False):
    """The module of cfg's problem (space, forms, dirichlet_condition, errors); with `limit`, the module
    of its Signorini variational inequality (paper eq. (8))."""
    return (LIMITS if limit else PROBLEMS)[cfg.problem.pde]


# the checks a problem's data pass before its first solve (problems/posed.py: the scalar problem's)
POSED = {"poisson": posed.check}


def check_posed(cfg, domain, u_exact, eps_value):
    """ConfigError (on every rank) when the level's problem is not posed right, where its PDE has a check."""
    if cfg.problem.pde in POSED:
        POSED[cfg.problem.pde](cfg, domain, u_exact, eps_value)
