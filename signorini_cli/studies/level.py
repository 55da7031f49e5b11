"""A level's record: what one solve on one mesh gives a study's table."""
from dataclasses import dataclass, field

from ..solve import solver


@dataclass
class Level:
    """One level's record: mesh size, ε, solver outcome, errors, wall time."""
    index: int
    n: int
    h: float
    dofs: int
    eps: float
    outcome: solver.Outcome
    errors: dict
    time_s: float
    extra: dict = field(default_factory=dict)
    solution: object = field(default=None, repr=False, compare=False)  # u_h, for nested iteration
    timings: dict = field(default_factory=dict, compare=False)  # t_* phases, memory (timing_columns)
