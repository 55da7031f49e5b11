"""The per-level stability report: continuation steps, linear fallback, the final Newton correction,
the penetration max_Γc [u_h]_+, and on request the Jacobian's condition number (Level.extra columns)."""
import math

from ..solve import solver
from . import verification

# the solver's own columns; `penetration` joins them unless the verification measures take it
SOLVER_COLUMNS = ("continuation_steps", "linear_fallback", "final_correction", "condition")


def report(cfg, problem, trace, outcome, dofs):
    """The stability columns this study's config calls for, in a fixed order."""
    solver_cfg, columns = cfg.solver, {}
    if solver_cfg.strategy in ("continuation", "auto"):
        columns["continuation_steps"] = outcome.continuation_steps
    # on every level of a study whose larger levels may solve iteratively (linear: auto in 2-D)
    if solver.linear_kind(solver_cfg, problem.dim, math.inf) == "iterative" and solver_cfg.linear_fallback:
        columns["linear_fallback"] = outcome.linear_fallback
    columns["final_correction"] = outcome.correction
    if "penetration" not in verification.measures(cfg):  # else the verification column has it
        columns["penetration"] = trace.penetration()  # max_Γc [w_h]_+ (the problem's trace)
    if solver_cfg.condition_max_dofs > 0:
        small = dofs <= solver_cfg.condition_max_dofs and outcome.converged
        columns["condition"] = condition_number(problem) if small else None
    return columns


def condition_number(problem):
    """lambda_max / lambda_min of the Jacobian at u_h on the free dofs (Lanczos estimate from CG)."""
    lam_min, lam_max = solver.condition_estimate(problem.J, problem.bcs, problem.u_h.function_space.mesh.comm,
                                                 contact=problem.contact)
    return lam_max / lam_min
