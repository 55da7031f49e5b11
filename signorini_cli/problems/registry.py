"""The problems by PDE: a study reaches its function space, forms, boundary condition and errors only
through the module problem_of(cfg) returns, so a new PDE is one new module here."""
import importlib

# cfg.problem.pde -> the compliance problem's module, and the module of its ε → 0 limit (the Signorini VI)
PROBLEMS = {"poisson": "compliance", "elasticity": "elasticity"}
LIMITS = {"poisson": "vi"}


def problem_of(cfg, limit=False):
    """The module of cfg's problem (space, forms, dirichlet_condition, errors); with `limit`, the module
    of its Signorini variational inequality (paper eq. (8))."""
    pde = getattr(cfg.problem, "pde", "poisson")
    name = (LIMITS if limit else PROBLEMS)[pde]
    return importlib.import_module(f"{__package__}.{name}")
