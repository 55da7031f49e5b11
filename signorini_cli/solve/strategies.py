"""The one solver path: every nonlinear solve of the package (refinement levels, reference solutions, the
Signorini VI, ε-sweeps) is built here, with the initial guess (zero, or nested iteration from the previous
level), ε-continuation, the success test, the fallback from an iterative to a direct linear solve and the
split assembly; `auto` combines them."""
import dataclasses
import logging
import math
from contextlib import contextmanager
from dataclasses import dataclass

from dolfinx import fem

from ..system.timing import Phases
from . import check, preflight, solver
from .transfer import transfer

logger = logging.getLogger(__name__)
EASY_ITS = 3  # a continuation step that took at most this many Newton iterations was easy
MAX_FACTOR = 0.9  # a continuation step shrunk beyond eps_{k+1}/eps_k = 0.9 is not worth taking
DIVERGED_CONTINUATION = "DIVERGED_MAX_CONTINUATION_STEPS"
# the residual check (checked): at most this many exact Newton steps after a solve that passed the success test.
# From an iterate with error e ||u||, exact Newton leaves ~e^2: from 1e-2 to below EXACT_TOL in 4 steps
EXACT_STEPS = 5
# the check's own bounds (the polish's, kept apart so that tuning the polish cannot move the check): an exact
# correction <= EXACT_TOL ||u_h|| keeps the algebraic error of every reported quantity below 1e-6 of it
EXACT_TOL = 1e-13
EXACT_STALL = 0.5  # a correction at least half the previous one: the round-off floor is reached
# the error of a Newton step's own linear solve, relative to the step (error_bound): LU's round-off (backward
# stable, kappa(J) <= 1e10), and CG + AMG stopped at ||B r|| <= linear_rtol ||B F||: kappa(BJ) linear_rtol,
# kappa(BJ) <= 100 for BoomerAMG/GAMG on these Jacobians
LINEAR_ERROR = {"direct": 1e-6, "iterative": 100.0}
SMOOTH_ALPHA = 2.0  # the smallest alpha whose contact Jacobian is Lipschitz: quadratic convergence (error_bound)
# option names that choose SNES's Krylov method or preconditioner: the residual check then solves with its own
USER_LINEAR = ("ksp_", "pc_", "sub_")
CONVERGED_EXACT = "CONVERGED_EXACT_NEWTON"  # the success test passed, but only exact Newton steps reached the root
DIVERGED_EXACT = "DIVERGED_EXACT_NEWTON"  # ... and exact Newton steps from its iterate did not converge


@dataclass(frozen=True)
class Problem:
    """One discrete problem; u_h holds the iterate, eps is the Constant the forms use (None for the
    Signorini VI, which has no ε). With `bounds` (lower, upper PETSc vectors) it is the VI
    lower <= u_h <= upper, solved by PETSc's reduced-space semismooth Newton (paper eq. (8))."""
    F: object
    J: object
    u_h: fem.Function
    bcs: list
    eps: fem.Constant
    eps_target: float
    dim: int
    split: object = None  # problems.forms.Split: Newton assembles the load and stiffness once per solve
    bounds: tuple = None
    contact: object = None  # contact.ContactTerm: the Γ_C terms assembled beside the UFL forms
    near_nullspace: object = None  # PETSc.NullSpace for AMG (elasticity's rigid motions)


def problem(forms, u_h, bcs, eps, eps_value, dim, bounds=None):
    """The Problem of problems.forms.Forms `forms` (the split and the contact term included) at eps_value."""
    return Problem(forms.F, forms.J, u_h, bcs, eps, eps_value, dim, forms.split, bounds, forms.contact,
                   forms.near_nullspace)


def solve(solver_cfg, problem, previous=None, monitor=None, phases=None):
    """Solve `problem` by solver_cfg.strategy, `previous` being the last converged level's u_h
    (or None); u_h ends as the final iterate. Returns the level's Outcome. `monitor(snes, its, fnorm)`
    sees every Newton iteration of every solve; `phases` (timing.Phases) gets the solve's times and,
    with solver.linear_floor, the level's linear floor (Outcome.floor_s)."""
    with newton_for(solver_cfg, problem, monitor, phases) as newton:
        outcome = checked(newton, problem, STRATEGIES[solver_cfg.strategy](newton, problem, previous, solver_cfg))
        if solver_cfg.linear_floor and outcome.converged:
            outcome = dataclasses.replace(outcome, floor_s=newton.snes.linear_floor())
        return outcome


@contextmanager
def newton_for(solver_cfg, problem, monitor=None, phases=None):
    """The Newton solver of `problem`, destroyed on leaving: for a sequence of solves on one problem
    (an ε-sweep, see descend); `solve` is the one-shot form."""
    newton = Newton(solver_cfg, problem, monitor, phases or Phases())
    try:
        yield newton
    finally:
        newton.destroy()


def descend(newton, problem, eps, solver_cfg, solved_eps):
    """Solve at `eps` from the current u_h, the solution at the larger `solved_eps`; if Newton fails and
    the strategy continues in ε (continuation, auto), ε-continuation from solved_eps down to eps.
    u_h ends as the last solution that converged. Returns the Outcome."""
    problem.eps.value = eps
    guess = problem.u_h.x.array.copy()
    first = checked(newton, problem, newton.run(eps))
    if first.converged or solver_cfg.strategy not in ("continuation", "auto"):
        if not first.converged:
            _restore(problem.u_h, guess)
        return first
    _restore(problem.u_h, guess)
    settings = dataclasses.replace(solver_cfg.continuation, start=solved_eps)
    reached = continue_eps(newton, dataclasses.replace(problem, eps_target=eps), settings)
    return combine([first, checked(newton, problem, reached)])


def checked(newton, problem, outcome):
    """The residual check of a solve that passed the success test: the exact Newton correction at its
    iterate must be at most EXACT_TOL ||u_h||, where the algebraic error of every reported quantity is below
    1e-6 of it. The success test sees only the iterates' own steps, and a stationary or one-sweep linear
    solver, a damped line search or a lagged Jacobian makes small steps far from the root. The correction is
    solved with the preconditioner of the last Newton step (check.borrowed_solve), or, when the user's PETSc
    options chose it, in a fresh KSP of the study's own linear solver; it is not solved where the study's own
    last two Newton steps already bound the error (error_bound). Else exact Newton steps follow, up to
    EXACT_STEPS, until the correction passes or stalls at its round-off floor (below stol ||u_h||, no longer
    halving: the polish's rule); the Outcome says how many it took."""
    if not outcome.converged or problem.bounds is not None:  # the VI: PETSc's test on its reduced residual
        return outcome
    own = not newton.cfg.petsc_options
    bound = error_bound(newton) if own else None
    if bound is not None and bound <= EXACT_TOL:
        return dataclasses.replace(outcome, correction=bound)
    options = None if not _user_preconditioner(newton.cfg) else _own_linear_options(newton, problem)
    stol = newton.cfg.stol or EXACT_TOL
    previous = None
    with newton.snes.phases("newton"):
        for taken in range(EXACT_STEPS + 1):
            delta, size, unorm = check.exact_correction(newton.snes, options)
            if options is None and size > EXACT_TOL * unorm:  # a step may follow: Newton's own, solved as a
                if delta is not None:  # Newton step is (the borrowed solve is only within 1e-3 of it)
                    delta.destroy()
                delta, size, unorm = check.exact_correction(newton.snes, _own_linear_options(newton, problem),
                                                            refactor=newton.linear == "direct" and own)
            small = size <= EXACT_TOL * unorm
            floor = previous is not None and size <= stol * unorm and size >= EXACT_STALL * previous
            if small or floor or delta is None or taken == EXACT_STEPS:
                break
            newton.snes.take(delta)
            delta.destroy()
            previous = size
    if delta is not None:
        delta.destroy()
    return _checked_outcome(outcome, taken, small or floor, size / unorm if unorm > 0 else size)


def error_bound(newton):
    """A bound on the error of the final iterate / ||u_h|| from the last two full Newton steps of the study's
    own solver, or None. Steps that contract by Θ = ||delta_k|| / ||delta_{k-1}|| <= 1/2, Θ not growing
    in Newton's local phase (it shrinks with the error at quadratic convergence: Deuflhard, Newton Methods,
    2004, Sect. 2.1), leave an error of at most the sum of the steps to come, Θ ||delta_k|| / (1 - Θ); the
    last step's own linear solve adds at most LINEAR_ERROR ||delta_k||. Not for Eisenstat-Walker's loose
    linear solves, and only where Newton converges quadratically: a contact term with alpha >= 2, whose
    Jacobian alpha [w]_+^(alpha-1) is Lipschitz. Below, a step can still change the active set after a tiny
    contraction (alpha = 1, eps = 1e-5, N = 32 in an eps-sweep: the bound passed where the exact correction
    needed one more step, L2 then off by 1e-7)."""
    contact = newton.problem.contact
    if newton.snes.last_steps is None or newton.cfg.inexact or contact is None or contact.alpha < SMOOTH_ALPHA:
        return None
    step, previous, unorm = newton.snes.last_steps
    theta = step / previous
    if theta > 0.5 or unorm <= 0:
        return None
    linear = LINEAR_ERROR[newton.linear] * (1.0 if newton.linear == "direct" else newton.cfg.linear_rtol)
    return (theta / (1 - theta) + linear) * step / unorm


def _user_preconditioner(solver_cfg):
    """Whether the user's PETSc options choose SNES's linear solver or preconditioner: then its PC may be no
    approximate inverse of J (Jacobi, none), and the check solves with the study's own one instead."""
    return any(name.startswith(USER_LINEAR) for name, _ in solver_cfg.petsc_options)


def _own_linear_options(newton, problem):
    """The KSP and PC options of the study's own linear solver on this level (a direct solve, or CG + AMG to
    linear_rtol), without the user's."""
    own = dataclasses.replace(newton.cfg, petsc_options=())
    options = solver.petsc_options(own, problem.dim, linear=newton.linear, dofs=newton.dofs)
    return {key: value for key, value in options.items() if key.startswith(("ksp_", "pc_"))}


def _checked_outcome(outcome, taken, passed, correction):
    """The Outcome after `taken` exact Newton steps; `correction`: the last exact correction / ||u_h||."""
    if taken == 0 and passed:
        return dataclasses.replace(outcome, correction=correction)
    reason = (CONVERGED_EXACT if passed else DIVERGED_EXACT) if taken else DIVERGED_EXACT
    logger.info("the success test passed at an iterate %.2e ||u_h|| from the root: %d exact Newton step(s) %s",
                correction, taken, "reached it" if passed else "did not")
    steps = outcome.steps + ((outcome.steps[-1][0] if outcome.steps else None, taken, reason),)
    return dataclasses.replace(outcome, converged=passed, reason=reason, newton_its=outcome.newton_its + taken,
                               correction=correction, steps=steps)


def plain(newton, problem, previous, solver_cfg):
    """Newton from u_h = 0 (u_D on Γ_D) at the target eps."""
    newton.initial_guess(None)
    return newton.run(problem.eps_target)


def nested(newton, problem, previous, solver_cfg):
    """Newton at the target eps from the previous level's solution (nested iteration)."""
    newton.initial_guess(previous)
    return newton.run(problem.eps_target)


def continuation(newton, problem, previous, solver_cfg):
    """eps-continuation from u_h = 0 (plain Newton for the VI, which has no eps)."""
    newton.initial_guess(None)
    if problem.eps is None:
        return newton.run(None)
    return continue_eps(newton, problem, solver_cfg.continuation)


def auto(newton, problem, previous, solver_cfg):
    """Nested iteration; if Newton fails at the target eps, eps-continuation from the same guess."""
    newton.initial_guess(previous)
    guess = problem.u_h.x.array.copy()
    first = newton.run(problem.eps_target)
    if first.converged or problem.eps is None:
        return first
    logger.info("Newton failed at eps=%.3g (%s): eps-continuation", problem.eps_target, first.reason)
    _restore(problem.u_h, guess)
    return combine([first, continue_eps(newton, problem, solver_cfg.continuation)])


STRATEGIES = {"plain": plain, "nested": nested, "continuation": continuation, "auto": auto}


class Handoff:
    """The last converged level's u_h on its way to the next level's initial guess, which moves it onto
    its own mesh and leaves the moved function here in its place: the coarser mesh is let go of before
    the finer level's solve (memory per dof), and a level that fails still hands the last
    converged solution on (the same function on nested meshes)."""

    def __init__(self, u_h=None):
        self.u_h = u_h

    def onto(self, V):
        self.u_h = transfer(self.u_h, V, extend=True)
        return self.u_h


def initial_guess(u_h, previous):
    """Zero, or the previous level's solution (a Function or a Handoff) moved onto u_h's mesh (exact for P1
    on nested meshes, MPI-correct: transfer.transfer; extended affinely beyond a curved boundary the
    coarser mesh does not reach). Dirichlet values are set by the solver."""
    if isinstance(previous, Handoff):
        previous = previous.onto(u_h.function_space) if previous.u_h is not None else None
    elif previous is not None:
        previous = transfer(previous, u_h.function_space, extend=True)
    u_h.x.array[:] = 0.0 if previous is None else previous.x.array
    u_h.x.scatter_forward()


def continue_eps(newton, problem, settings):
    """Solve at eps_0 = max(start, eps) > eps_1 > ... > eps, each from the last solution. The ratio
    eps_{k+1}/eps_k starts at `factor`, is squared after an easy step (<= EASY_ITS Newton iterations)
    and square-rooted after a failure (which restores the last solution); at most max_steps solves."""
    target, factor = problem.eps_target, settings.factor
    solved, eps_next, outcomes = None, max(settings.start, target), []
    saved = problem.u_h.x.array.copy()
    while len(outcomes) < settings.max_steps:
        outcome = newton.run(eps_next)
        outcomes.append(outcome)
        if outcome.converged:
            solved, saved = eps_next, problem.u_h.x.array.copy()
            if solved <= target:
                break
            factor = factor**2 if outcome.newton_its <= EASY_ITS else factor
        else:
            _restore(problem.u_h, saved)
            factor = math.sqrt(factor)
            if solved is None or factor > MAX_FACTOR:
                break
        eps_next = max(target, solved * factor)
    return _continuation_outcome(outcomes, bool(solved is not None and solved <= target))


def _continuation_outcome(outcomes, reached):
    total = combine(outcomes)
    reason = total.reason if reached or not outcomes[-1].converged else DIVERGED_CONTINUATION
    return dataclasses.replace(total, converged=reached, reason=reason, continuation_steps=len(outcomes))


def combine(outcomes):
    """One Outcome for consecutive solves of a level: the last one's verdict, summed counts."""
    last = outcomes[-1]
    return solver.Outcome(
        converged=last.converged, reason=last.reason,
        newton_its=sum(o.newton_its for o in outcomes), linear_its=sum(o.linear_its for o in outcomes),
        residuals=sum((o.residuals for o in outcomes), ()),
        continuation_steps=sum(o.continuation_steps for o in outcomes),
        linear_fallback=any(o.linear_fallback for o in outcomes), steps=sum((o.steps for o in outcomes), ()),
        correction=last.correction)


class Newton:
    """One level's SNES, run at any eps; falls back to a direct linear solve (for the rest of the
    level) when an iterative one fails and linear_fallback is on."""

    def __init__(self, solver_cfg, problem, monitor=None, phases=None):
        self.cfg, self.problem = solver_cfg, problem
        self.dofs = solver.global_dofs(problem.u_h.function_space)
        self.linear = solver.linear_kind(solver_cfg, problem.dim, self.dofs)
        # the VI keeps PETSc's own test of vinewtonrsls, on the reduced residual
        test = solver.success_test(solver_cfg) if problem.bounds is None else None
        self.snes = solver.NewtonSolver(problem.F, problem.J, problem.u_h, problem.bcs, self.options(),
                                        monitor=monitor, test=test, phases=phases, split=problem.split,
                                        contact=problem.contact, near_nullspace=problem.near_nullspace)
        if problem.bounds is not None:
            self.snes.snes.setVariableBounds(*problem.bounds)
        self.fell_back = False

    def options(self, linear=None):
        """The PETSc options of this problem (solver.petsc_options; vinewtonrsls for the VI, the user's
        petsc_options still last)."""
        opts = solver.petsc_options(self.cfg, self.problem.dim, linear=linear, dofs=self.dofs)
        if self.problem.bounds is not None:
            opts["snes_type"] = "vinewtonrsls"
            opts.update(dict(self.cfg.petsc_options))
        return opts

    def initial_guess(self, previous):
        """u_h = 0 or the previous level's solution (initial_guess), timed as phase 'transfer'."""
        with self.snes.phases("transfer"):
            initial_guess(self.problem.u_h, previous)

    def run(self, eps):
        """One SNES solve at `eps` from the current u_h (with a fallback solve: both timed as 'newton'); a PETSc
        error (an option PETSc accepted on the trial system of preflight but not here) is bad input."""
        with self.snes.phases("newton"), preflight.petsc_errors(f" in the solve at eps={eps}"):
            return self._run(eps)

    def _run(self, eps):
        if self.problem.eps is not None:
            self.problem.eps.value = eps
        start = self.problem.u_h.x.array.copy()
        outcomes = [self.snes.solve()]
        if outcomes[-1].reason == solver.LINEAR_SOLVE_FAILED and self._can_fall_back():
            if self.problem.u_h.function_space.mesh.comm.rank == 0:
                logger.warning("iterative linear solve failed at eps=%.3g: falling back to a direct solve", eps)
            self.linear, self.fell_back = "direct", True
            self.snes.configure(self.options(linear="direct"))
            _restore(self.problem.u_h, start)
            outcomes.append(self.snes.solve())
        outcomes = [dataclasses.replace(o, steps=((eps, o.newton_its, o.reason),)) for o in outcomes]
        return dataclasses.replace(combine(outcomes), linear_fallback=self.fell_back)

    def destroy(self):
        self.snes.destroy()

    def _can_fall_back(self):
        return self.linear == "iterative" and self.cfg.linear_fallback


def _restore(u_h, values):
    u_h.x.array[:] = values
    u_h.x.scatter_forward()
