"""The problems by name (`problem.pde`): each module gives space, forms, dirichlet_condition and errors."""
from . import compliance, elasticity

PROBLEMS = {"poisson": compliance, "elasticity": elasticity}


def problem_of(cfg):
    """The module of cfg.problem.pde (a miss is a bug: the config loader checked the name)."""
    return PROBLEMS[cfg.problem.pde]
