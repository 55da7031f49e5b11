"""The residual check (strategies.checked): whatever linear solver, preconditioner or line search the user's
PETSc options choose, a level is converged only at an iterate whose exact Newton correction is below
1e-13 ||u_h||, so every converged level's error agrees with a default solve's to 1e-6."""
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from signorini_cli import studies
from signorini_cli.solve import strategies
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


def test_own_ksp_refactors_at_the_iterate(make_config, monkeypatch):
    """Without options of the user's the check solves with SNES's own direct KSP, whose factorisation is
    that of the last Newton step's Jacobian: at a moved iterate it must factor J(u) anew, and give the
    correction a fresh KSP gives (two LU solves of one system: round-off, observed ~1e-15)."""
    cfg = make_config(alpha=1.5, mesh={"refinements": [8]})
    problem = solved_problem(cfg, monkeypatch)
    with strategies.newton_for(cfg.solver, problem) as newton:
        newton.run(cfg.epsilon(0.125))
        problem.u_h.x.array[:] *= 1.5  # another iterate, another active set: a stale factorisation is wrong
        options = {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"}
        found = []
        for own in (True, False):
            newton.snes.x.set(0.0)
            problem.u_h.vector.copy(newton.snes.x)
            delta, size, _ = newton.snes.exact_correction(options, own_ksp=own)
            found.append((delta, size))
        assert found[0][1] == pytest.approx(found[1][1], rel=1e-12)
        difference = found[0][0].copy()
        difference.axpy(-1.0, found[1][0])
        assert difference.norm() <= 1e-12 * found[1][1]
        for obj in (found[0][0], found[1][0], difference):
            obj.destroy()



def test_failed_check_leaves_snes_usable(make_config, monkeypatch):
    """A check whose factorisation on SNES's own KSP fails (a singular J: zero pivots) says so, and the next
    solve on the same SNES (as ε-continuation would make) still converges."""
    cfg = make_config(mesh={"refinements": [8]})
    problem = solved_problem(cfg, monkeypatch)
    options = {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"}
    with strategies.newton_for(cfg.solver, problem) as newton:
        assert newton.run(cfg.epsilon(0.125)).converged
        assemble = newton.snes.assemble_jacobian

        def singular(J, whole=False):
            assemble(J, whole)
            J.zeroEntries()
            J.assemble()
        saved = newton.snes.A.copy()  # the stiffness lives in J between steps (the split): put it back after
        monkeypatch.setattr(newton.snes, "assemble_jacobian", singular)
        delta, size, _ = newton.snes.exact_correction(options, own_ksp=True)
        assert delta is None and size == float("inf")
        monkeypatch.setattr(newton.snes, "assemble_jacobian", assemble)
        saved.copy(newton.snes.A, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        saved.destroy()
        problem.u_h.x.array[:] = 0.0
        assert newton.run(cfg.epsilon(0.125)).converged
