"""The residual check (strategies.checked): whatever linear solver, preconditioner or line search the user's
PETSc options choose, a level is converged only at an iterate whose exact Newton correction is below
1e-13 ||u_h||, so every converged level's error agrees with a default solve's to 1e-6."""
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from signorini_cli import studies
from signorini_cli.solve import check, solver, strategies
from conftest import solved_problem

# options whose iterates are no Newton steps; each made the success test pass far from the root (the
# step of a stationary iteration is small, not its error): L2 off by up to 5.6 % (Jacobi at N = 64)
HOSTILE = [
    pytest.param({"pc_type": "jacobi"}, 100000, id="jacobi-preonly-max-it"),
    pytest.param({"pc_type": "none"}, 50, id="pc-none"),
    pytest.param({"ksp_type": "preonly", "pc_type": "jacobi"}, 50, id="preonly-jacobi"),
    pytest.param({"ksp_type": "richardson", "ksp_max_it": 1, "pc_type": "jacobi"}, 50, id="richardson-one-it"),
    pytest.param({"ksp_type": "preonly", "pc_type": "bjacobi", "sub_pc_type": "ilu"}, 50, id="ilu"),
    pytest.param({"snes_linesearch_type": "basic", "snes_linesearch_damping": 0.01}, 50, id="damped"),
]
REFINEMENTS = [8, 16]
# the bar: a converged level's L2 error within 1e-6 (relative) of a tight default solve's
REL = 1e-6


def check_no_false_convergence(comm, make_config, options, max_it):
    tight = studies.run_study(make_config(mesh={"refinements": REFINEMENTS}), comm=comm)
    cfg = make_config(mesh={"refinements": REFINEMENTS}, solver={"petsc_options": options, "max_it": max_it})
    levels = studies.run_study(cfg, comm=comm)
    for level, reference in zip(levels, tight):
        if level.outcome.converged:
            assert level.errors["L2"] == pytest.approx(reference.errors["L2"], rel=REL), level.outcome.reason
        else:
            assert level.outcome.reason != strategies.CONVERGED_EXACT


@pytest.mark.parametrize("options, max_it", HOSTILE)
def test_no_false_convergence(make_config, options, max_it):
    check_no_false_convergence(MPI.COMM_SELF, make_config, options, max_it)


@pytest.mark.mpi
@pytest.mark.parametrize("options, max_it", HOSTILE)
def test_no_false_convergence_mpi(make_config, options, max_it):
    assert MPI.COMM_WORLD.size == 2
    check_no_false_convergence(MPI.COMM_WORLD, make_config, options, max_it)


def test_jacobi_levels_reach_the_root_by_exact_steps(make_config):
    """Jacobi sweeps as the linear solver: the success test passes at a small sweep, the exact Newton steps
    after it reach the root, and the row says so (reason CONVERGED_EXACT_NEWTON)."""
    cfg = make_config(mesh={"refinements": REFINEMENTS}, solver={"petsc_options": {"pc_type": "jacobi"},
                                                                  "max_it": 100000})
    levels = studies.run_study(cfg, comm=MPI.COMM_SELF)
    assert [lv.outcome.reason for lv in levels] == [strategies.CONVERGED_EXACT] * 2
    assert all(lv.outcome.correction <= 1e-13 for lv in levels)  # solver.POLISH_TOL


def test_default_solve_needs_no_exact_step(make_config):
    """The study's own solvers end at the root: the check costs one correction, takes no step."""
    levels = studies.run_study(make_config(mesh={"refinements": REFINEMENTS}), comm=MPI.COMM_SELF)
    assert all(lv.outcome.converged and lv.outcome.reason != strategies.CONVERGED_EXACT for lv in levels)


def pc_setups():
    """How many preconditioner set-ups (factorisations, AMG hierarchies) this process has made so far."""
    return PETSc.Log.Event("PCSetUp").getPerfInfo()["count"]


@pytest.mark.parametrize("linear", ["direct", "iterative"])
def test_borrowed_correction_at_a_moved_iterate(make_config, monkeypatch, linear):
    """At an iterate away from the last Newton step's (another active set: alpha = 1.5, u scaled by 1.5) the
    check's correction, solved with the last step's preconditioner, equals a fresh KSP's exact one within
    check.CHECK_RTOL's factor (kappa(BJ) CHECK_RTOL, observed ~1e-5), and a stale factorisation alone is wrong."""
    PETSc.Log.begin()
    cfg = make_config(alpha=1.5, mesh={"refinements": [16]}, solver={"linear": linear})
    problem = solved_problem(cfg, monkeypatch)
    with strategies.newton_for(cfg.solver, problem) as newton:
        newton.run(cfg.epsilon(0.125))
        problem.u_h.x.array[:] *= 1.5
        own = strategies._own_linear_options(newton, problem)
        found = []
        for options in (None, own):
            problem.u_h.vector.copy(newton.snes.x)
            setups = pc_setups()
            found.append((*check.exact_correction(newton.snes, options)[:2], pc_setups() - setups))
        assert found[0][1] == pytest.approx(found[1][1], rel=10 * check.CHECK_RTOL)
        difference = found[0][0].copy()
        difference.axpy(-1.0, found[1][0])
        assert difference.norm() <= 10 * check.CHECK_RTOL * found[1][1]
        assert found[0][2] == 0 and found[1][2] >= 1  # borrowed: no set-up; fresh: its own
        for obj in (found[0][0], found[1][0], difference):
            obj.destroy()


def test_default_check_sets_up_no_preconditioner(make_config, monkeypatch):
    """A default level's check (CG + AMG here) adds no preconditioner set-up to the solve's own: the same
    number of PCSetUp with the check as the Newton steps made (no second AMG hierarchy, no peak-memory rise)."""
    PETSc.Log.begin()
    cfg = make_config(mesh={"refinements": [32]}, solver={"linear": "iterative", "polish": 0})
    problem = solved_problem(cfg, monkeypatch)
    with strategies.newton_for(cfg.solver, problem) as newton:
        outcome = newton.run(cfg.epsilon(1 / 32))
        setups = pc_setups()
        assert strategies.error_bound(newton) is None or strategies.error_bound(newton) > strategies.EXACT_TOL
        checked = strategies.checked(newton, problem, outcome)
        assert checked.converged and checked.reason == outcome.reason and pc_setups() == setups


@pytest.mark.parametrize("linear", ["direct", "iterative"])
def test_error_bound_bounds_the_exact_correction(make_config, monkeypatch, linear):
    """Where the last two Newton steps give a bound (strategies.error_bound) the exact correction at the
    iterate (a fresh KSP's) is below it (or at its round-off floor), the check would pass, and the check
    returns that bound without solving."""
    cfg = make_config(mesh={"refinements": [32]}, solver={"linear": linear})
    problem = solved_problem(cfg, monkeypatch)
    with strategies.newton_for(cfg.solver, problem) as newton:
        outcome = newton.run(cfg.epsilon(1 / 32))
        bound = strategies.error_bound(newton)
        assert bound is not None and bound <= strategies.EXACT_TOL  # the default polish reaches it
        delta, size, unorm = check.exact_correction(newton.snes, strategies._own_linear_options(newton, problem))
        delta.destroy()
        # F(u) in floating point floors the computed correction (observed 5e-17 ||u|| here); 1e-15 bounds that
        assert size / unorm <= max(bound, 1e-15) and size <= strategies.EXACT_TOL * unorm
        assert strategies.checked(newton, problem, outcome).correction == bound


def test_error_bound_needs_two_contracting_full_steps():
    """No bound without two full steps, for a step that halves no more, or for loose (inexact) solves; with
    Θ = 1e-3 it is Θ/(1 - Θ) ||delta_k|| plus the linear solve's share."""
    class Fake:
        linear, cfg = "direct", type("Cfg", (), {"inexact": False, "linear_rtol": 1e-10})()
        snes = type("Snes", (), {"last_steps": None})()
        problem = type("Problem", (), {"contact": type("Contact", (), {"alpha": 2.0})()})()
    fake = Fake()
    assert strategies.error_bound(fake) is None
    fake.snes.last_steps = (0.6, 1.0, 1.0)
    assert strategies.error_bound(fake) is None
    fake.snes.last_steps = (1e-12, 1e-9, 2.0)
    expected = (1e-3 / (1 - 1e-3) + strategies.LINEAR_ERROR["direct"]) * 1e-12 / 2.0
    assert strategies.error_bound(fake) == pytest.approx(expected, rel=1e-15)
    fake.problem.contact.alpha = 1.5  # no quadratic convergence: no bound
    assert strategies.error_bound(fake) is None
    fake.problem.contact.alpha = 2.0
    fake.cfg.inexact = True
    assert strategies.error_bound(fake) is None


def test_alpha_1_sweep_is_checked(make_config, monkeypatch):
    """alpha = 1 (semismooth Newton): the ε-sweep's level where the last steps' bound passed at an iterate the
    exact correction still moved (ε = 1e-5, N = 32) is checked, and an exact Newton step reaches the root."""
    cfg = make_config(alpha=1.0, mesh={"refinements": [32]})
    problem = solved_problem(cfg, monkeypatch)
    with strategies.newton_for(cfg.solver, problem) as newton:
        assert strategies.error_bound(newton) is None
        for eps in (1e-3, 1e-4, 1e-5):
            outcome = strategies.descend(newton, problem, eps, cfg.solver, eps * 10)
            assert outcome.converged and outcome.correction <= strategies.EXACT_TOL


def test_failed_check_leaves_snes_usable(make_config, monkeypatch):
    """A check whose preconditioner, borrowed from SNES's own KSP, fails (a singular J: zero pivots) says so, and
    the next solve on the same SNES (as ε-continuation would make) still converges."""
    cfg = make_config(mesh={"refinements": [8]})
    problem = solved_problem(cfg, monkeypatch)
    with strategies.newton_for(cfg.solver, problem) as newton:
        assert newton.run(cfg.epsilon(0.125)).converged
        assemble = newton.snes.assemble_jacobian

        def singular(J, whole=False):
            assemble(J, whole)
            J.zeroEntries()
            J.assemble()
        saved = newton.snes.A.copy()  # the stiffness lives in J between steps (the split): put it back after
        monkeypatch.setattr(newton.snes, "assemble_jacobian", singular)
        delta, size, _ = check.exact_correction(newton.snes)
        assert delta is None and size == float("inf")
        monkeypatch.setattr(newton.snes, "assemble_jacobian", assemble)
        saved.copy(newton.snes.A, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        saved.destroy()
        problem.u_h.x.array[:] = 0.0
        assert newton.run(cfg.epsilon(0.125)).converged


@pytest.mark.fast
def test_amg_lag_by_dimension(make_config):
    """CG + AMG sets its preconditioner up every 2nd Newton step in 2-D and every 3rd in 3-D (a nested 3-D level's
    3 steps: one set-up); a direct solve is never lagged (a lagged LU is a chord method)."""
    cfg = make_config().solver
    assert solver.petsc_options(cfg, 2, linear="iterative")["snes_lag_preconditioner"] == 2
    assert solver.petsc_options(cfg, 3, linear="iterative")["snes_lag_preconditioner"] == 3
    assert "snes_lag_preconditioner" not in solver.petsc_options(cfg, 2, linear="direct")
