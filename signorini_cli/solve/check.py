"""Newton's exact correction at a solve's final iterate, for the residual check (strategies.checked): solved with
the preconditioner the last Newton step built (its AMG hierarchy or LU factors: no second one is set up, so the
check raises neither the time nor the peak memory of a level), or in a fresh KSP of the study's own options when
the user's options chose SNES's preconditioner."""
import math

from petsc4py import PETSc

from .solver import _set_options

# GMRES with the borrowed preconditioner B stops at ||B r|| <= CHECK_RTOL ||B F|| (zero initial guess), so the
# computed delta is within kappa(BJ) CHECK_RTOL ||delta*|| of the exact correction delta* = J^{-1} F: its norm
# is delta*'s within a factor 1 +- 1e-2 for kappa(BJ) <= 10 (an AMG hierarchy or the LU factors of a nearby J):
# enough to compare it with 1e-13 ||u_h||
CHECK_RTOL = 1e-3
CHECK_MAX_IT = 30  # beyond this, B no longer fits J(u) (another active set): it is set up anew on J(u)


def exact_correction(newton, options=None, refactor=False):
    """(delta, ||delta||, ||u||) for Newton's exact correction delta = J(u)^{-1} F(u) at the final iterate of
    `newton` (solver.NewtonSolver): to first order the algebraic error of u, whichever solver produced u. Solved
    with SNES's own preconditioner (borrowed_solve), with `options` in a fresh KSP, or (`refactor`) by SNES's own
    direct KSP factoring J(u) anew. ||delta|| is inf (delta None) when that linear solve fails."""
    b, delta = newton.b.duplicate(), newton.x.duplicate()
    with newton.phases("assemble_residual"):
        newton.assemble_residual(newton.x, b)  # leaves x in u, where the Jacobian is assembled
    with newton.phases("assemble_jacobian"):
        newton.assemble_jacobian(newton.A)
    if refactor:
        solved = refactored_solve(newton, b, delta)
    else:
        solved = borrowed_solve(newton, b, delta) if options is None else fresh_solve(newton, options, b, delta)
    b.destroy()
    norm = delta.norm() if solved else math.inf
    if not solved or not math.isfinite(norm):
        delta.destroy()
        return None, math.inf, newton.x.norm()
    return delta, norm, newton.x.norm()


def borrowed_solve(newton, b, delta):
    """J delta = b by GMRES preconditioned with SNES's own PC as the last Newton step left it (reused, not set
    up on J(u)); if that does not converge, with the PC set up on J(u) as a Newton step would. Whether solved."""
    own = newton.snes.getKSP()
    pc = own.getPC()
    ksp = PETSc.KSP().create(newton.u.function_space.mesh.comm)
    ksp.setType("gmres")
    ksp.setPC(pc)
    ksp.setOperators(newton.A)
    ksp.setTolerances(rtol=CHECK_RTOL, atol=0.0, max_it=CHECK_MAX_IT)
    try:
        for reuse in (True, False):
            pc.setReusePreconditioner(reuse)
            delta.set(0.0)
            ksp.solve(b, delta)
            if ksp.getConvergedReason() > 0:
                return True
        own.reset()  # a failed factorisation leaves MUMPS unusable for SNES's next solve
        return False
    finally:
        pc.setReusePreconditioner(False)  # SNES sets it again at its next Jacobian (its lag)
        ksp.destroy()


def refactored_solve(newton, b, delta):
    """J delta = b by SNES's own KSP, its PC set up on J(u) (a direct solver's new numeric factorisation on the
    symbolic one of the Newton steps). Whether solved."""
    ksp = newton.snes.getKSP()
    ksp.getPC().setReusePreconditioner(False)
    ksp.setOperators(newton.A)
    delta.set(0.0)
    ksp.solve(b, delta)
    if ksp.getConvergedReason() > 0:
        return True
    ksp.reset()  # a failed factorisation leaves MUMPS unusable for SNES's next solve
    return False


def fresh_solve(newton, options, b, delta):
    """J delta = b in a fresh KSP with `options` under its own prefix (deleted after). Whether solved."""
    ksp = PETSc.KSP().create(newton.u.function_space.mesh.comm)
    prefix = f"{newton.prefix}exact_"
    _set_options(prefix, options)
    ksp.setOptionsPrefix(prefix)
    ksp.setFromOptions()
    ksp.setOperators(newton.A)
    delta.set(0.0)
    ksp.solve(b, delta)
    solved = ksp.getConvergedReason() > 0
    for key in [key for key in PETSc.Options().getAll() if key.startswith(prefix)]:
        PETSc.Options().delValue(key)
    ksp.destroy()
    return solved
