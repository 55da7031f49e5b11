"""Newton's method for one level: PETSc SNES on the residual and Jacobian forms, with a success test
that cannot pass far from the solution, NaN/Inf detection, and a Jacobian condition estimate."""
import ctypes
import dataclasses
import functools
import itertools
import math
import time
from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc

from ..system.timing import Phases
from .assembly import StoredRows, dirichlet_mask, load_part, varying_rows

REASONS = {getattr(PETSc.SNES.ConvergedReason, name): name
           for name in dir(PETSc.SNES.ConvergedReason) if name.isupper()}
CONVERGED_RESIDUAL = PETSc.SNES.ConvergedReason.CONVERGED_FNORM_ABS
CONVERGED_STEP = PETSc.SNES.ConvergedReason.CONVERGED_SNORM_RELATIVE
DIVERGED_NAN = PETSc.SNES.ConvergedReason.DIVERGED_FNORM_NAN
DIVERGED_MAX_IT = PETSc.SNES.ConvergedReason.DIVERGED_MAX_IT
# failures after which u_k may sit at a root that ||F|| cannot show below its round-off floor:
# the line search (newtonls) or the trust region (newtontr) found no decrease from u_k
STALLED = {PETSc.SNES.ConvergedReason.DIVERGED_LINE_SEARCH, PETSc.SNES.ConvergedReason.DIVERGED_TR_DELTA,
           PETSc.SNES.ConvergedReason.DIVERGED_INNER}
FULL_STEP_TOL = 1e-8  # a step with lambda >= 1 - 1e-8 is the full Newton step (round-off in the norms)
# ... or one that falls short of it by at most 1e-12 ||u||: x - x_before of a step near round-off
# (1e-14 ||u|| after success) carries a relative error far above FULL_STEP_TOL
FULL_STEP_ROUNDOFF = 1e-12
TR_RADIUS = 0.2  # newtontr's first radius, relative to max(||u_0||, sqrt(dofs)) (PETSc: 0.2 ||u_0||)
LINEAR_SOLVE_FAILED = "DIVERGED_LINEAR_SOLVE"
# polish: after the success test, Newton goes on until the predicted error of the iterate is
# below POLISH_TOL ||u||. Reported errors are >= 1e-7 ||u_h|| (the smallest: the eps-sweep's model error and
# data-push's L2_ref), so 1e-13 keeps the algebraic error of each below 1e-6 of it.
POLISH_TOL = 1e-13
POLISH_STALL = 0.5  # a step at least half the previous one does not contract: the round-off floor is reached
_prefixes = itertools.count()


@dataclass(frozen=True)
class Outcome:
    """What Newton did: iterations, PETSc's reason, residual history; never raises on divergence.
    A level solved in several SNES solves (attempts, continuation) sums their counts; `steps` holds
    (eps, newton_its, reason) of each solve in order."""
    converged: bool
    reason: str
    newton_its: int
    linear_its: int
    residuals: tuple
    # diagnostics, kept in the table's stability columns and study.h5, not part of the outcome's identity
    # (a level read back from study.h5 by --resume compares equal without them)
    continuation_steps: int = field(default=0, compare=False)
    linear_fallback: bool = field(default=False, compare=False)
    steps: tuple = field(default=(), compare=False)
    correction: float = field(default=None, compare=False)  # last Newton correction / ||u_h||: the error estimate
    floor_s: float = field(default=None, compare=False)  # the level's linear floor (NewtonSolver.linear_floor)


# linear: auto solves 2-D levels up to this many dofs with MUMPS (robust on the 1/eps boundary rows of
# the stiff suite, whose levels stay below it) and larger ones with CG + AMG, faster and smaller there
# (make bench: bench/results.md, "Solver choices")
DIRECT_MAX_DOFS_2D = 20_000
# CG + AMG: set up the preconditioner at Newton steps 0, 2, 4 ... in 2-D (make bench), 0, 3, 6 ... in 3-D, where a
# nested level takes 3 steps: the elastic 32^3 level sets up GAMG once instead of twice (half its linear floor),
# with the same 105 CG iterations and L2 equal to 6e-16
LAG_PRECONDITIONER = {2: 2, 3: 3}


def linear_kind(solver_cfg, dim, dofs=0):
    """'direct' or 'iterative': linear: auto is MUMPS LU in 2-D up to DIRECT_MAX_DOFS_2D dofs and
    CG + AMG above, and in 3-D (32^3 cells: 3.5 s against 23 s)."""
    if solver_cfg.linear != "auto":
        return solver_cfg.linear
    return "direct" if dim == 2 and dofs <= DIRECT_MAX_DOFS_2D else "iterative"


def global_dofs(V):
    """The number of unknowns of V over all ranks."""
    return V.dofmap.index_map.size_global * V.dofmap.index_map_bs


def petsc_options(solver_cfg, dim, linear=None, dofs=0):
    """The PETSc options a solver config stands for on a level with `dofs` unknowns (`linear`
    overrides the linear solver kind, as the fallback to direct does); the user's petsc_options come
    last and win. The SNES tolerances serve PETSc's own test only (vinewtonrsls): SuccessTest
    replaces it in the compliance solves."""
    opts = {"snes_type": solver_cfg.method, "snes_max_it": solver_cfg.max_it,
            "snes_rtol": solver_cfg.rtol, "snes_atol": solver_cfg.atol, "snes_stol": 0.0}
    if solver_cfg.method == "newtonls":
        opts["snes_linesearch_type"] = solver_cfg.line_search
    if (linear or linear_kind(solver_cfg, dim, dofs)) == "direct":
        opts.update(ksp_type="preonly", pc_type="lu", pc_factor_mat_solver_type="mumps")
    else:
        opts.update(ksp_type="cg", ksp_rtol=solver_cfg.linear_rtol, **_multigrid(solver_cfg.preconditioner))
        # the AMG hierarchy of one Newton step serves the next one (two in 3-D) too: CG still solves with
        # the true Jacobian (unlike a lagged LU, a chord method), and nested iteration needs 2-3 steps
        opts["snes_lag_preconditioner"] = LAG_PRECONDITIONER[dim]
        if solver_cfg.inexact:
            opts["snes_ksp_ew"] = ""  # Eisenstat-Walker: linear tolerance from the Newton residual
    opts.update(dict(solver_cfg.petsc_options))
    return opts


# BoomerAMG with aggressive coarsening on the finest level (2 paths): at N = 1024 (1.05M dofs) the
# hierarchy takes 108 MiB less than hypre's default, and its set-up and CG solve are faster on 1 and on
# 2 ranks (the default's set-up does not speed up on 2 ranks); CG needs a few more iterations (make bench)
BOOMERAMG = {"pc_hypre_boomeramg_agg_nl": 1, "pc_hypre_boomeramg_agg_num_paths": 2}


def _multigrid(preconditioner):
    if preconditioner == "gamg":
        return {"pc_type": "gamg"}
    return {"pc_type": "hypre", "pc_hypre_type": "boomeramg", **BOOMERAMG}


@dataclass(frozen=True)
class SuccessTest:
    """Converged when every norm is finite and one of these holds:
    (R) ||F(u_k)|| <= max(atol, rtol * scale), scale = the norm of the load without the penalty
        term (never relative to the initial residual, which carries 1/eps);
    (S) the full Newton direction delta_k that led to u_k (before the line search damps it) is at
        most stol * ||u_k||: near a root Newton's step is the error to first order, and it is not
        scaled by 1/eps (the 1/eps rows of J and F cancel). It catches the tiny-eps regime where
        round-off in the 1/eps terms keeps ||F|| above rtol * scale;
    (C) in Newton's local phase (the last two steps full, lambda = 1, and ||delta_k|| <=
        sqrt(stol) ||u_k||) the quadratic model predicts the error of u_k, Θ^2 ||delta_k|| with Θ the
        contraction ||delta_k|| / ||delta_{k-1}|| (Deuflhard, Newton Methods, 2004, Sect. 2.1), below
        stol * ||u_k||, and the simplified Newton correction ||J(u_{k-1})^{-1} F(u_k)|| (one more
        solve with the last Jacobian, an estimate of the error of u_k) confirms it. Saves the
        iteration that (S) would spend to see the error it already made small. Outside the local
        phase a damped step makes Θ meaningless and a Jacobian with another active set can shrink
        the simplified correction by eps (alpha = 1, eps = 1e-8, plain Newton on N = 128: accepted
        at L2 = 0.16 instead of 1.0e-4 before these two conditions)."""
    rtol: float
    atol: float
    stol: float
    max_it: int
    scale: float
    polish: int = 0  # at most this many Newton steps after the test passes (NewtonSolver, polished)

    def __call__(self, its, fnorm, unorm, step=None, previous=None, correction=None):
        """The SNES reason for iterate `its`, or None to go on. `step`, `previous`: ||delta_k||,
        ||delta_{k-1}|| (None if unknown); `correction()` computes the simplified correction."""
        if not all(math.isfinite(v) for v in (fnorm, unorm, step or 0.0)):
            return DIVERGED_NAN
        if fnorm <= max(self.atol, self.rtol * self.scale):
            return CONVERGED_RESIDUAL
        if self.step_small(step, unorm):
            return CONVERGED_STEP
        if correction is not None and self.error_predicted_small(step, previous, unorm):
            if self.step_small(correction(), unorm):
                return CONVERGED_STEP
        return DIVERGED_MAX_IT if its >= self.max_it else None

    def step_small(self, step, unorm):
        """Test (S): a Newton correction of at most stol * ||u||."""
        return step is not None and step <= self.stol * unorm

    def error_predicted_small(self, step, previous, unorm):
        """The quadratic model's prediction in test (C), for contracting steps that are already small
        (||delta_k|| <= sqrt(stol) ||u||: the Jacobian, its active set included, barely changes)."""
        if step is None or not previous or step >= previous or step > math.sqrt(self.stol) * unorm:
            return False
        return (step / previous) ** 2 * step <= self.stol * unorm

    def polished(self, step, previous, unorm):
        """Whether Newton steps after success can stop at this iterate (two full steps in a row): its error,
        Θ ||delta_k|| to first order for steps contracting by Θ = ||delta_k|| / ||delta_{k-1}|| (Deuflhard 2004,
        Sect. 2.1), is at most POLISH_TOL ||u||. Not the quadratic model's Θ^2 ||delta_k|| of test (C): a
        semismooth step (α = 1) that changed the active set leaves more (ε-sweep, α = 1, ε = 1e-4, N = 32:
        Θ^2 ||delta|| = 4e-15 ||u|| with the model error 5e-5 off)."""
        return step is not None and bool(previous) and step / previous * step <= POLISH_TOL * unorm

    def stalled(self, step, previous):
        """Whether a step after success no longer contracts (Θ >= POLISH_STALL): round-off, e.g. in the 1/eps
        rows, floors the steps. Not a test at success itself, where a semismooth step (α = 1) that changed
        the active set contracts little (ε-sweep, α = 1, ε = 1e-4, N = 32: stopped 5e-5 off in L2)."""
        return step is not None and bool(previous) and step >= POLISH_STALL * previous


def success_test(solver_cfg, scale=1.0):
    return SuccessTest(solver_cfg.rtol, solver_cfg.atol, solver_cfg.stol, solver_cfg.max_it, scale,
                       solver_cfg.polish)


class NewtonSolver:
    """SNES on F(u) = 0 with Jacobian J, Dirichlet conditions `bcs`; u holds the initial guess.
    `test`, a SuccessTest (its scale measured at every solve), replaces PETSc's convergence test;
    without one PETSc's own test runs on the options' tolerances (vinewtonrsls, whose residual is
    the reduced one). `monitor(snes, its, fnorm)` is called at every Newton iteration; `phases`
    (timing.Phases) records form compilation and the residual and Jacobian assemblies. With `split`
    (problems.forms.Split) the load and the stiffness are assembled once per solve, and each Newton iteration
    assembles only the rest (the contact term, and the stiffness times u with one quadrature point).
    `contact` (contact.ContactTerm, Forms.contact) adds the Γ_C terms integrated beside the UFL forms to
    every residual and Jacobian (timed as phase 'contact' within the assemblies)."""

    def __init__(self, F, J, u, bcs, options, prefix=None, monitor=None, test=None, phases=None, split=None,
                 contact=None, near_nullspace=None):
        self.phases = phases or Phases()
        with self.phases("forms"):
            # a form keeps a list of its cells (8 MiB at N = 1024): those used once per solve or only by the
            # linear floor are compiled when needed (JIT-cached) and let go of after
            self.F, self.a = F, fem.form(J)  # the whole Jacobian: sparsity, lifting, the linear floor
            varying = F if split is None else split.F_varying
            self.L_vary = fem.form(varying)
            self.a_vary = None if split is None or split.J_varying is None else fem.form(split.J_varying)
            self.fixed = None if split is None else fem.form(split.F_fixed)
            self.F_load = load_part(varying)
        self.b_fixed = None  # the split's load vector (assemble_fixed)
        self.u, self.bcs, self.test = u, bcs, test
        self.last_steps = None  # (||delta_k||, ||delta_{k-1}||, ||u_k||) of the last solve's last two full steps
        self.contact = contact
        self.fixed_dofs = dirichlet_mask(u.function_space, bcs) if contact is not None else None
        self.b = fem_petsc.create_vector(self.L_vary)
        with self.phases("assemble_jacobian"):  # the sparsity pattern: part of the Jacobian's cost
            self.A = fem_petsc.create_matrix(self.a)
            self.K_rows = None if split is None else self.stiffness(self.A, fem.form(split.J_fixed))
        if near_nullspace is not None:  # what AMG must coarsen exactly (elasticity: the rigid motions)
            self.A.setNearNullSpace(near_nullspace)
        self.x = u.vector.duplicate()  # SNES's own iterate: never u.vector, which F() overwrites
        self.snes = PETSc.SNES().create(u.function_space.mesh.comm)
        self.snes.setFunction(self._residual, self.b)
        self.snes.setJacobian(self._jacobian, self.A)
        self.prefix = prefix or f"signorini_{next(_prefixes)}_"
        self.configure(options)
        if monitor is not None:
            self.snes.setMonitor(monitor)

    def configure(self, options):
        """(Re)apply PETSc options under this solver's prefix, e.g. to fall back to a direct solve."""
        _clear_options(self.prefix)
        _set_options(self.prefix, options)
        self.snes.setOptionsPrefix(self.prefix)
        self.snes.setFromOptions()
        self.snes.getKSP().setFromOptions()
        self.snes.setConvergenceHistory(reset=True)
        self.line_search = self.snes.getType() == "newtonls"
        self._user_radius = f"{self.prefix}snes_tr_delta0" in PETSc.Options().getAll()
        if self.test is None:
            return
        self.snes.setConvergenceTest(self._converged)
        if self.line_search:
            self.snes.setLineSearchPreCheck(self._record_direction)

    def solve(self):
        """Run Newton from the current u; return the Outcome and leave the iterate in u."""
        self.u.vector.copy(self.x)
        fem_petsc.set_bc(self.x, self.bcs)  # start from an iterate that satisfies u = u_D on Γ_D
        if self.fixed is not None:
            self.assemble_fixed()
        if self.contact is not None:
            with self.phases("contact"):
                self.contact.prepare()  # the data term at this solve's eps
        self._test = dataclasses.replace(self.test, scale=self.load_scale()) if self.test else None
        self._direction, self._previous, self._confirmed, self._extra_linear_its = None, None, None, 0
        self._accepted, self._kept, self.last_steps = None, None, None  # see _keep, _converged
        self._before, self._full = self.x.duplicate(), (False, False)  # iterate before the step; full steps
        if self.snes.getType() == "newtontr" and not self._user_radius:
            self._set_trust_radius()
        self.snes.solve(None, self.x)
        reason, residuals = self._ended()
        self.x.copy(self.u.vector)
        self.u.x.scatter_forward()
        for vec in (self._before, self._kept):
            if vec is not None:
                vec.destroy()
        if reason in STALLED and self._at_root():
            reason = CONVERGED_STEP  # no decrease is possible at round-off, and none is needed
        if reason == PETSc.SNES.ConvergedReason.DIVERGED_LINEAR_SOLVE:
            self.snes.getKSP().reset()  # a failed factorisation leaves MUMPS unusable for the next solve
        unorm = self.x.norm()
        finite = bool(np.all(np.isfinite(residuals))) and np.isfinite(unorm)
        estimate = self._confirmed if self._confirmed is not None else self._direction
        return Outcome(converged=bool(reason > 0 and finite),
                       reason=REASONS.get(reason, str(reason)) if finite else "DIVERGED_FNORM_NAN",
                       newton_its=self.snes.getIterationNumber(),
                       linear_its=self.snes.getLinearSolveIterations() + self._extra_linear_its,
                       residuals=tuple(float(r) for r in residuals),
                       correction=estimate / unorm if estimate is not None and unorm > 0 else None)

    def _ended(self):
        """SNES's reason and residual history; when a step after success failed, the success's reason and
        the history up to the last iterate that passed, which goes back into x."""
        reason = self.snes.getConvergedReason()
        residuals, _ = self.snes.getConvergenceHistory()
        if self._accepted is not None and reason < 0:
            reason, _, self._confirmed, its = self._accepted
            self._kept.copy(self.x)
            self.last_steps = None  # they led to the failed iterate, not to this one
            residuals = residuals[:its + 1]
        return reason, residuals

    def _at_root(self):
        """Whether the full Newton direction at the stalled iterate passes test (S): ||F|| then
        only fails to decrease because it is at its round-off floor."""
        if self._test is None or self._direction is None or self.snes.getKSP().getConvergedReason() < 0:
            return False
        return self._test.step_small(self._direction, self.x.norm())

    def take(self, delta):
        """u <- u - delta: a full Newton step from the final iterate (check.exact_correction)."""
        self.x.axpy(-1.0, delta)
        self.x.copy(self.u.vector)
        self.u.x.scatter_forward()

    def _set_trust_radius(self):
        """PETSc starts newtontr with radius delta0 * ||u_0||, degenerate from u_0 = 0 (round-off
        on Γ_D makes it 1e-17): scale delta0 so the radius is TR_RADIUS * max(||u_0||, sqrt(dofs))."""
        unorm = self.x.norm()
        scale = max(unorm, math.sqrt(self.x.getSize()))
        PETSc.Options()[f"{self.prefix}snes_tr_delta0"] = TR_RADIUS * scale / unorm if unorm > 0 else TR_RADIUS
        self.snes.setFromOptions()

    def load_scale(self):
        """||F_load(u_D)||: the volume part of the residual (load f, and the Dirichlet lifting) with
        the Dirichlet rows zeroed; if that vanishes, the whole residual there; else 1."""
        x_D = self.x.duplicate()
        x_D.set(0.0)
        fem_petsc.set_bc(x_D, self.bcs)
        saved = self.u.vector.copy()
        scale = (self._assembled_norm(fem.form(self.F_load), x_D)
                 or self._assembled_norm(self.L_vary, x_D, with_contact=True) or 1.0)
        saved.copy(self.u.vector)
        self.u.x.scatter_forward()
        for vec in (x_D, saved):
            vec.destroy()
        return scale

    def destroy(self):
        for obj in (self.snes, self.A, self.b, self.x, self.b_fixed):
            if obj is not None:
                obj.destroy()
        _clear_options(self.prefix)

    def stiffness(self, A, K):
        """Assemble the split's fixed Jacobian K (the stiffness, identity rows on Γ_D) into A and return K's
        rows that the rest of J adds to (StoredRows): each Jacobian resets them to K and adds the rest, so
        that no second matrix of the level's size is kept (memory per dof)."""
        fem_petsc.assemble_matrix(A, K, bcs=self.bcs)
        A.assemble()
        return StoredRows.of(A, varying_rows(self.u.function_space, self.a_vary, self.contact))

    def assemble_fixed(self):
        """The split's load vector, at this solve's eps (manufactured data may depend on it), kept
        before its ghost update: each residual adds it."""
        with self.phases("assemble_residual"):
            self.b_fixed = self.b_fixed or fem_petsc.create_vector(self.fixed)
            with self.b_fixed.localForm() as b_local:
                b_local.set(0.0)
            fem_petsc.assemble_vector(self.b_fixed, self.fixed)

    def _add_fixed(self, b):
        """b += the split's load, on the local and ghost entries (before b's ghost update)."""
        if self.b_fixed is not None:
            with b.localForm() as b_local, self.b_fixed.localForm() as fixed_local:
                b_local.array_w[:] += fixed_local.array_r

    def _assembled_norm(self, L, x, with_contact=False):
        x.copy(self.u.vector)
        self.u.x.scatter_forward()
        b = fem_petsc.assemble_vector(L)
        self._add_fixed(b)
        if with_contact:
            self._add_contact(b)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fem_petsc.set_bc(b, self.bcs, x, -1.0)
        norm = b.norm()
        b.destroy()
        return norm

    def _residual(self, snes, x, F):
        with self.phases("assemble_residual"):
            self.assemble_residual(x, F)

    def assemble_residual(self, x, F, whole=False):
        """F(x) with the Dirichlet rows x - u_D, leaving x in u; `whole`: from the whole form, as if
        there were no split."""
        x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        x.copy(self.u.vector)
        self.u.x.scatter_forward()
        with F.localForm() as f_local:
            f_local.set(0.0)
        fem_petsc.assemble_vector(F, fem.form(self.F) if whole else self.L_vary)
        if not whole:
            self._add_fixed(F)
        self._add_contact(F)
        fem_petsc.apply_lifting(F, [self.a], bcs=[self.bcs], x0=[x], scale=-1.0)
        F.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fem_petsc.set_bc(F, self.bcs, x, -1.0)

    def _jacobian(self, snes, x, J, P):
        with self.phases("assemble_jacobian"):
            self.assemble_jacobian(J)

    def assemble_jacobian(self, J, whole=False):
        """J at the iterate in u, identity rows on Γ_D: the split's stiffness plus the rest, or
        (`whole`, or no split) the whole form."""
        if self.K_rows is None or whole:
            J.zeroEntries()
            fem_petsc.assemble_matrix(J, self.a, bcs=self.bcs)
        else:
            self.K_rows.reset(J)
            if self.a_vary is not None:
                fem_petsc.assemble_matrix(J, self.a_vary, bcs=self.bcs)  # adds; Γ_D diagonal stays 1
        if self.contact is not None:
            with self.phases("contact"):
                self.contact.add_jacobian(J, self.fixed_dofs)  # off the Γ_D rows and columns
        J.assemble()

    def _add_contact(self, b):
        """b += the Γ_C terms assembled beside UFL, at the iterate in u (before b's ghost update)."""
        if self.contact is not None:
            with self.phases("contact"), b.localForm() as b_local:
                self.contact.add_residual(b_local.array_w)

    def linear_floor(self):
        """Seconds to assemble and solve once the Jacobian system at the current u with this solver's
        own linear solver and tolerance, in a fresh KSP: the floor a Newton solve is measured against."""
        A, b, x = self.A.duplicate(), self.b.duplicate(), self.x.duplicate()
        ksp = PETSc.KSP().create(self.u.function_space.mesh.comm)
        ksp.setOptionsPrefix(self.prefix)
        ksp.setFromOptions()
        self.u.vector.copy(x)
        comm = self.u.function_space.mesh.comm
        comm.barrier()
        start = time.perf_counter()
        self.assemble_jacobian(A, whole=True)
        self.assemble_residual(x, b, whole=True)
        ksp.setOperators(A)
        x.set(0.0)
        ksp.solve(b, x)
        seconds = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
        for obj in (ksp, A, b, x):
            obj.destroy()
        return seconds

    def _record_direction(self, x, y):
        """Line-search pre-check: remember the full Newton direction's norm and the iterate it starts
        from; change nothing."""
        self._direction = y.norm()
        x.copy(self._before)
        return False

    def _full_step(self, x):
        """Whether the line search took the whole Newton step to x (lambda = 1): the quadratic model
        of test (C) describes only Newton's local phase, never damped steps."""
        self._before.aypx(-1.0, x)  # x - x_before, the step taken
        return self._before.norm() >= (1 - FULL_STEP_TOL) * self._direction - FULL_STEP_ROUNDOFF * x.norm()

    def _converged(self, snes, its, norms):
        xnorm, _, fnorm = norms
        if not self.line_search and its > 0:
            # newtontr: the KSP solution is the full Newton direction, before the radius cuts it
            self._direction = snes.getKSP().getSolution().norm()
        step = None if its == 0 else self._direction
        if its > 0 and snes.getKSP().getConvergedReason() < 0:
            step = None  # a failed linear solve says nothing about the error
        self._confirmed = None
        if self.line_search and step is not None:
            self._full = (self._full[1], self._full_step(snes.getSolution()))
        # (C) and the polish after two full steps only; newtontr's steps near a root are its full Newton
        # directions (the radius no longer cuts them), and (C) needs newtonls's simplified correction
        previous = self._previous if all(self._full) or not self.line_search else None
        correction = self._simplified_correction if self.line_search else None
        unorm = xnorm if its > 0 else self.x.norm()
        # the last two full Newton steps at this iterate: what bounds its error (strategies.error_bound)
        self.last_steps = (step, previous, unorm) if self.line_search and previous and step is not None else None
        reason = self._decide(its, fnorm, unorm, step, previous, correction)
        self._previous = step
        return reason

    def _decide(self, its, fnorm, unorm, step, previous, correction):
        """The success test, then up to `polish` more Newton steps until SuccessTest.polished: each step
        after success is the error of the iterate before it to first order, and at quadratic
        convergence leaves an error of its square. A step after success that test (S) would reject
        withdraws the success (Newton goes on under the test); a failed one ends at the success's iterate."""
        test = self._test
        if self._accepted is not None:
            if step is None or not all(math.isfinite(v) for v in (fnorm, unorm, step)):
                return DIVERGED_NAN  # solve() goes back to the accepted iterate
            if test.stol == 0 or test.step_small(step, unorm):
                self._keep(self._accepted[0], self._accepted[1], step, its)
                done = its - self._accepted[1] >= test.polish or its >= test.max_it
                done = done or test.polished(step, previous, unorm) or test.stalled(step, previous)
                return self._accepted[0] if done else None
            self._accepted = None
        reason = test(its, fnorm, unorm, step, previous, correction)
        if reason is None or reason < 0 or its >= test.max_it or test.polish == 0 or \
                test.polished(step, previous, unorm):
            return reason
        self._keep(reason, its, self._confirmed if self._confirmed is not None else self._direction, its)
        return None

    def _keep(self, reason, success_its, estimate, its):
        """Remember the success (reason, iteration) and the latest iterate that passed (iteration `its`), with
        its error estimate: solve() returns to it if a later step fails (a line search at round-off)."""
        self._kept = self._kept or self.x.duplicate()
        self.snes.getSolution().copy(self._kept)
        self._accepted = (reason, success_its, estimate, its)

    def _simplified_correction(self):
        """||J(u_{k-1})^{-1} F(u_k)||: one more solve with the factors/preconditioner of the last step."""
        ksp = self.snes.getKSP()
        y = self.b.duplicate()
        ksp.solve(self.b, y)  # self.b holds F(u_k): the line search evaluated it there
        self._extra_linear_its += ksp.getIterationNumber()
        self._confirmed = y.norm() if ksp.getConvergedReason() > 0 else math.inf
        y.destroy()
        return self._confirmed


def condition_estimate(J, bcs, comm, max_its=20000, contact=None):
    """(lambda_min, lambda_max) of the assembled Jacobian (with the `contact` term beside UFL, at its
    u_h) on the free dofs, from the Lanczos tridiagonal that unpreconditioned CG builds
    (KSPComputeEigenvalues); the rhs vanishes on Dirichlet rows, so the identity rows bcs put there
    never enter the Krylov space."""
    A = fem_petsc.assemble_matrix(fem.form(J), bcs=bcs)
    if contact is not None:
        contact.add_jacobian(A, dirichlet_mask(contact.u_h.function_space, bcs))
    A.assemble()
    b = A.createVecRight()
    start, end = b.getOwnershipRange()
    b.setArray(np.sin(np.arange(start, end) * 618.0339887))  # deterministic, rich in every eigenvector
    fem_petsc.set_bc(b, bcs, scale=0.0)
    ksp = PETSc.KSP().create(comm)
    ksp.setOperators(A)
    ksp.setType("cg")
    ksp.getPC().setType("none")
    ksp.setTolerances(rtol=1e-14, atol=0.0, max_it=max_its)
    ksp.setComputeEigenvalues(True)
    x = b.duplicate()
    ksp.solve(b, x)
    eigenvalues = np.real(ksp.computeEigenvalues())
    for obj in (ksp, A, b, x):
        obj.destroy()
    eigenvalues = eigenvalues[eigenvalues > 0]
    return (float(eigenvalues.min()), float(eigenvalues.max())) if eigenvalues.size else (math.nan, math.nan)


def _set_options(prefix, options):
    opts = PETSc.Options()
    for key, value in options.items():
        opts[f"{prefix}{key}"] = value


def _clear_options(prefix):
    opts = PETSc.Options()
    for key in list(opts.getAll()):
        if key.startswith(prefix):
            if _option_used(key):  # remembered for unused_options: deleting the option forgets it
                _used.add(key[len(prefix):])
            opts.delValue(key)


# --- PETSc options nobody read -------------------------------------------------------------------

_used = set()  # option names (without prefix) some solver of this process read before it was cleared


def forget_read_options():
    """Start a new record for unused_options (a run's own options, not an earlier run's in this process)."""
    _used.clear()


def unused_options(names):
    """The option names among `names` (the user's solver.petsc_options) that no solver has read so
    far, neither one already destroyed nor one alive under a signorini prefix: misspelt, or options
    of an object the study does not create (a GMRES restart for CG, a hypre option for LU)."""
    alive = {key.split("_", 2)[2] for key in PETSc.Options().getAll()
             if key.startswith("signorini_") and key.count("_") >= 2 and _option_used(key)}
    return [name for name in names if name not in _used and name not in alive]


def _option_used(key):
    """PETSc's own record (PetscOptionsUsed) of whether `key` was read; petsc4py 3.18 does not wrap it."""
    used = ctypes.c_int(0)  # PetscBool
    _petsc_library().PetscOptionsUsed(None, key.encode(), ctypes.byref(used))
    return bool(used.value)


@functools.lru_cache(maxsize=1)
def _petsc_library():
    """The libpetsc this process runs (petsc4py's), found among the loaded libraries."""
    with open("/proc/self/maps") as maps:
        path = next(line.split()[-1] for line in maps if "/libpetsc" in line)
    library = ctypes.CDLL(path)
    library.PetscOptionsUsed.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.POINTER(ctypes.c_int)]
    return library
