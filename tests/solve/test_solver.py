"""Numerical faults: NaN or Inf in the residual, the Jacobian or the solution fail the level with a
reason, never an exception; the study then continues or stops per solver.on_failure. The success test,
the config -> PETSc options map, and the condition estimate."""
import csv
import dataclasses
import types

import numpy as np
import pytest
import scipy.linalg
import yaml
from mpi4py import MPI

from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from signorini_cli import studies
from signorini_cli.app import cli
from signorini_cli.config import ConfigError
from signorini_cli.solve import assembly, solver
from conftest import BASE, merge, solved_problem

NAN_DATA = {"exact": None, "f": "sqrt(x - 0.5)"}  # NaN at every quadrature point with x < 0.5
INF_DATA = {"exact": None, "f": "exp(1000*x)"}  # overflows to Inf for x > 0.71


@pytest.mark.parametrize("problem, value", [pytest.param(NAN_DATA, "nan", id="nan"),
                                            pytest.param(INF_DATA, "inf", id="inf")])
def test_nonfinite_data_refused_before_solving(make_config, problem, value):
    # the data are checked at the points the solve evaluates them (problems/posed.py), before level 0
    with pytest.raises(ConfigError, match=rf"problem.f: .* is {value} at \("):
        studies.run_study(make_config(problem=problem))


def patch_after(monkeypatch, name, calls, spoil):
    """Let NewtonSolver.<name> run, then spoil(args) from its `calls`-th call of each level on."""
    original, count = getattr(solver.NewtonSolver, name), {}

    def patched(self, snes, x, *rest):
        original(self, snes, x, *rest)
        count[id(self)] = count.get(id(self), 0) + 1
        if count[id(self)] >= calls:
            spoil(x, *rest)
    monkeypatch.setattr(solver.NewtonSolver, name, patched)


def test_inf_residual_mid_newton(make_config, monkeypatch):
    patch_after(monkeypatch, "_residual", 3, lambda x, F: F.set(float("inf")))
    (level, _) = studies.run_study(make_config())
    assert level.outcome.reason == "DIVERGED_FNORM_NAN" and level.outcome.newton_its >= 1


def test_nan_solution_with_finite_residual(make_config, monkeypatch):
    def spoil(x, F):
        x.array[0] = float("nan")  # the iterate itself, which the residual norm does not see
    patch_after(monkeypatch, "_residual", 3, spoil)
    (level, _) = studies.run_study(make_config())
    assert not level.outcome.converged and level.outcome.reason == "DIVERGED_FNORM_NAN"


@pytest.mark.parametrize("linear", ["direct", "iterative"])
def test_nan_jacobian_fails_the_linear_solve(make_config, monkeypatch, linear):
    patch_after(monkeypatch, "_jacobian", 2, lambda x, J, P: J.scale(float("nan")))
    (level, _) = studies.run_study(make_config(solver={"linear": linear}))
    assert not level.outcome.converged and level.outcome.reason == "DIVERGED_LINEAR_SOLVE"


def test_nonfinite_level_in_cli(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(merge(BASE, {"problem": NAN_DATA, "solver": {"on_failure": "stop"},
                                                "output": {"dir": str(tmp_path / "out"), "plots": False}})))
    assert cli.main(["run", str(path)]) == cli.EXIT_BAD_INPUT  # one line, nothing solved
    table = tmp_path / "out" / "t" / "rates.csv"  # refused before any level is recorded (or the table opened)
    assert not table.exists() or list(csv.DictReader(table.open())) == []


TEST = solver.SuccessTest(rtol=1e-10, atol=1e-12, stol=1e-8, max_it=50, scale=2.0)


def test_success_residual_relative_to_load_not_to_initial_residual():
    # from u = 0 with eps = 1e-8 the initial residual is ~1e7: a relative test with
    # rtol 1e-10 would pass at 1e-3; this one wants 1e-10 * the load's norm (2e-10)
    assert TEST(3, 1e-3, unorm=5.0) is None
    assert TEST(3, 1.9e-10, unorm=5.0) == solver.CONVERGED_RESIDUAL


def test_success_step_full_newton_correction():
    assert TEST(3, 1.0, unorm=5.0, step=4e-8) == solver.CONVERGED_STEP  # 4e-8 <= 1e-8 * 5
    assert TEST(3, 1.0, unorm=5.0, step=6e-8) is None


def test_success_prediction_needs_confirmation():
    calls = []

    def correction(value):
        return lambda: calls.append(value) or value

    # Θ = 1e-3/1e-1 = 1e-2: predicted error Θ^2 * 1e-3 = 1e-7 <= 1e-8 * 50
    assert TEST(3, 1.0, 50.0, step=1e-3, previous=1e-1, correction=correction(1e-7)) == solver.CONVERGED_STEP
    assert TEST(3, 1.0, 50.0, step=1e-3, previous=1e-1, correction=correction(1e-6)) is None
    assert calls == [1e-7, 1e-6]
    # not contracting, or predicted too large: no confirmation solve is spent
    assert TEST(3, 1.0, 50.0, step=1e-3, previous=1e-3, correction=correction(0.0)) is None
    assert TEST(3, 1.0, 50.0, step=1e-2, previous=1e-1, correction=correction(0.0)) is None
    assert calls == [1e-7, 1e-6]


def test_success_prediction_only_for_small_steps():
    # ||delta|| = 1e-3 > sqrt(1e-8) * 5 = 5e-4: outside the local phase, no prediction is trusted
    assert not TEST.error_predicted_small(1e-3, 1e3, 5.0)
    assert TEST.error_predicted_small(1e-4, 1e1, 5.0)  # Θ^2 ||delta|| = 1e-14 <= 5e-8


def test_success_not_fooled_by_damped_steps(make_config):
    # alpha = 1, eps = 1e-8, plain Newton from 0 on N = 128: the first step overshoots by 1/eps and the
    # line search damps it to lambda ~ 1e-8; a prediction from that step, confirmed with a Jacobian of
    # another active set, once accepted iterate 2 at L2 = 0.16. The solution has L2 = 1.0157e-4
    # (auto, docs/stability.md); plain needs 23 iterations.
    # pinned to the degree-6 rule these numbers were measured with: the trajectory is what is tested
    cfg = make_config(alpha=1.0, epsilon={"law": "constant", "theta": 1e-8}, mesh={"refinements": [128]},
                      solver={"strategy": "plain"}, contact_quadrature=6)
    (level,) = studies.run_study(cfg, comm=MPI.COMM_SELF)
    assert level.outcome.converged and level.errors["L2"] == pytest.approx(1.0157e-4, rel=1e-3)


@pytest.mark.parametrize("norms", [
    pytest.param(dict(fnorm=float("nan"), unorm=1.0), id="residual-nan"),
    pytest.param(dict(fnorm=1.0, unorm=float("inf")), id="iterate-inf"),
    pytest.param(dict(fnorm=1.0, unorm=1.0, step=float("nan")), id="step-nan"),
])
def test_success_nan_inf_diverge(norms):
    assert TEST(1, **norms) == solver.DIVERGED_NAN


def test_polished_by_the_first_order_estimate():
    # Θ = 9e-10 / 1e-5: estimated error Θ * 9e-10 = 8.1e-14 <= POLISH_TOL (1e-13) * ||u|| = 1e-13
    assert TEST.polished(9e-10, 1e-5, 1.0)
    # Θ = 1e-2: estimated 1e-11 > 1e-13, one more step (the quadratic model would have said 1e-13)
    assert not TEST.polished(1e-9, 1e-7, 1.0)
    # a step half the previous or more: the steps stopped contracting (round-off floor, after success)
    assert TEST.stalled(1e-15, 2e-15) and TEST.stalled(3e-15, 2e-15) and not TEST.stalled(0.9e-15, 2e-15)
    # no previous full step: no prediction
    assert not TEST.polished(1e-20, None, 1.0) and not TEST.stalled(1.0, None)


class FakeVec:
    """A PETSc vector's duplicate and copy, holding one number."""
    def __init__(self, value=0.0):
        self.value = value

    def duplicate(self):
        return FakeVec()

    def copy(self, other):
        other.value = self.value


class FakeSNES:
    def __init__(self, x):
        self.x, self.reason, self.history = x, 0, [1.0, 1.0, 1.0]  # ||F|| at iterates 0, 1, 2

    def getSolution(self):
        return self.x

    def getConvergedReason(self):
        return self.reason

    def getConvergenceHistory(self):
        return self.history, None


def fake_newton():
    """The state NewtonSolver._decide and _ended use, on one-number iterates (iterate k holds k)."""
    x = FakeVec()
    fake = types.SimpleNamespace(_test=dataclasses.replace(TEST, polish=3), _accepted=None, _kept=None,
                                 _confirmed=None, _direction=None, x=x, snes=FakeSNES(x))
    fake._keep = lambda *args: solver.NewtonSolver._keep(fake, *args)
    return fake


def step_to(fake, its, step, previous=None):
    fake.x.value = its
    fake.snes.history.append(1.0)
    return solver.NewtonSolver._decide(fake, its, 1.0, 5.0, step, previous, None)


def test_polish_failed_step_returns_to_the_last_iterate_that_passed():
    fake = fake_newton()
    assert step_to(fake, 3, 4e-8) is None  # (S) passes (4e-8 <= 1e-8 * 5): polish from iterate 3
    assert step_to(fake, 4, 3e-8) is None  # no previous full step: no prediction, go on
    assert step_to(fake, 5, float("nan")) == solver.DIVERGED_NAN
    fake.snes.reason = solver.DIVERGED_NAN
    reason, residuals = solver.NewtonSolver._ended(fake)
    assert reason == solver.CONVERGED_STEP and fake.x.value == 4 and len(residuals) == 5
    assert fake._confirmed == 3e-8  # the estimate of iterate 4: the step that led to it


def test_polish_withdraws_a_premature_success():
    fake = fake_newton()
    assert step_to(fake, 3, 4e-8) is None
    assert step_to(fake, 4, 1.0) is None  # the step after success is large: (S) rejects it, Newton goes on
    assert fake._accepted is None
    assert step_to(fake, 5, 1e-12, previous=1.0) == solver.CONVERGED_STEP  # and succeeds at 5, polished
    assert fake._accepted is None


def test_polish_not_stopped_by_a_stall_at_success():
    fake = fake_newton()
    step_to(fake, 2, 1e-4)
    # (S) passes at 3 with a step 0.4 of the previous (a semismooth step that changed the active set): polish
    assert step_to(fake, 3, 4e-8, previous=1e-7) is None
    assert step_to(fake, 4, 3e-8, previous=4e-8) == solver.CONVERGED_STEP  # stalled after success: stop


def test_polish_at_most_polish_steps():
    fake = fake_newton()
    assert step_to(fake, 3, 4e-8) is None
    assert [step_to(fake, its, 3e-8) for its in (4, 5, 6)] == [None, None, solver.CONVERGED_STEP]


def check_polish_steps(comm, make_config):
    # α = 2, ε = h (the demo), N = 4, 8, 16, against polish = 0, which stops at the success test
    polished = studies.run_study(make_config(mesh={"refinements": [4, 8, 16]}), comm=comm)
    plain = studies.run_study(make_config(mesh={"refinements": [4, 8, 16]}, solver={"polish": 0}), comm=comm)
    assert all(lv.outcome.converged and lv.outcome.correction is not None for lv in polished + plain)
    # at most solver.polish (3) Newton steps per level, none where the success test passed late enough
    # (observed 1, 1, 1)
    extra = [p.outcome.newton_its - q.outcome.newton_its for p, q in zip(polished, plain)]
    assert all(0 <= e <= 3 for e in extra) and sum(extra) >= 1
    # the same solution to the 1e-6, the polish moving the error by what stol allowed (observed
    # 3.4e-10, 1.3e-8 and 2.9e-13)
    for p, q in zip(polished, plain):
        assert p.errors["L2"] == pytest.approx(q.errors["L2"], rel=1e-6)


def test_polish_steps_serial(make_config):
    check_polish_steps(MPI.COMM_SELF, make_config)


@pytest.mark.mpi
def test_polish_steps_two_ranks(make_config):
    assert MPI.COMM_WORLD.size == 2
    check_polish_steps(MPI.COMM_WORLD, make_config)


def test_success_max_it():
    assert TEST(50, 1.0, 1.0, step=1.0) == solver.DIVERGED_MAX_IT
    assert TEST(50, 1e-11, 1.0) == solver.CONVERGED_RESIDUAL  # convergence wins on the last iteration


@pytest.mark.parametrize("dim, solver_cfg, expected", [
    pytest.param(2, {}, {"ksp_type": "preonly", "pc_factor_mat_solver_type": "mumps",
                         "snes_linesearch_type": "bt"}, id="2d-auto-direct"),
    pytest.param(3, {}, {"ksp_type": "cg", "pc_type": "hypre", "pc_hypre_type": "boomeramg"}, id="3d-auto-amg"),
    pytest.param(2, {"linear": "iterative", "preconditioner": "gamg", "inexact": True},
                 {"ksp_type": "cg", "pc_type": "gamg", "snes_ksp_ew": ""}, id="gamg-ew"),
    pytest.param(2, {"method": "newtontr"}, {"snes_type": "newtontr"}, id="trust-region"),
    pytest.param(2, {"line_search": "cp", "petsc_options": {"ksp_type": "gmres"}},
                 {"snes_linesearch_type": "cp", "ksp_type": "gmres"}, id="user-options-win"),
])
def test_petsc_options_from_config(make_config, dim, solver_cfg, expected):
    opts = solver.petsc_options(make_config(solver=solver_cfg).solver, dim)
    assert {key: opts.get(key) for key in expected} == expected
    assert ("snes_linesearch_type" in opts) == (opts["snes_type"] == "newtonls")
    assert "snes_ksp_ew" not in solver.petsc_options(make_config(solver=solver_cfg).solver, dim, linear="direct")


def test_condition_estimate_matches_dense_eigenvalues(make_config, monkeypatch):
    cfg = make_config(mesh={"refinements": [8]}, epsilon={"law": "constant", "theta": 1e-4})
    problem = solved_problem(cfg, monkeypatch)
    lam_min, lam_max = solver.condition_estimate(problem.J, problem.bcs, MPI.COMM_SELF, contact=problem.contact)
    A = fem_petsc.assemble_matrix(fem.form(problem.J), bcs=problem.bcs)
    problem.contact.add_jacobian(A, assembly.dirichlet_mask(problem.u_h.function_space, problem.bcs))
    A.assemble()
    free = np.setdiff1d(np.arange(A.getSize()[0]), problem.bcs[0].dof_indices()[0])
    eigenvalues = scipy.linalg.eigvalsh(A.convert("dense").getDenseArray()[np.ix_(free, free)])
    # N=8 (49 free dofs): CG to 1e-14 runs the full Lanczos process; observed agreement 1e-12
    assert lam_min == pytest.approx(eigenvalues[0], rel=1e-8)
    assert lam_max == pytest.approx(eigenvalues[-1], rel=1e-8)


# --- one matrix: the stiffness assembled into J once, the rows the Γ_C terms touch reset each step; the
# residual's stiffness part is a product with J ---------------------------------------------------------

def check_split_jacobian(comm, make_config, monkeypatch, rule):
    # α = 1.5, ε = 1e-2: the exact rule adds the penalty beside UFL, degree 6 through UFL's J_varying (ds)
    cfg = make_config(alpha=1.5, contact_quadrature=rule, epsilon={"law": "constant", "theta": 1e-2},
                      mesh={"refinements": [8]})
    problem = solved_problem(cfg, monkeypatch, comm)
    newton = solver.NewtonSolver(problem.F, problem.J, problem.u_h, problem.bcs, {}, split=problem.split,
                                 contact=problem.contact)
    newton.assemble_fixed()
    whole, x, F_whole = newton.A.duplicate(), newton.x.duplicate(), newton.b.duplicate()
    rng = np.random.default_rng(comm.rank)
    for _ in range(3):  # successive iterates with other active sets: each reset undoes the last step's terms
        x.setArray(rng.uniform(-1.0, 1.0, x.getLocalSize()))
        fem_petsc.set_bc(x, problem.bcs)
        # the residual: K x from J (whose Γ_C rows hold the last step's terms) against the whole form
        newton.assemble_residual(x, newton.b)
        newton.assemble_residual(x, F_whole, whole=True)  # leaves x in u: the Jacobian's point
        assert (newton.b - F_whole).norm() <= 1e-13 * F_whole.norm()
        newton.assemble_jacobian(newton.A)
        newton.assemble_jacobian(whole, whole=True)  # zeroed and assembled from the whole form
        difference = newton.A.copy()
        difference.axpy(-1.0, whole)
        # the same sums of the same element contributions in another order: round-off (observed ~1e-16)
        assert difference.norm() <= 1e-13 * whole.norm()
    for obj in (whole, difference, F_whole):
        obj.destroy()
    newton.destroy()


@pytest.mark.parametrize("rule", ["exact", 6])
def test_split_residual_and_jacobian_are_the_whole_forms(make_config, monkeypatch, rule):
    check_split_jacobian(MPI.COMM_SELF, make_config, monkeypatch, rule)


@pytest.mark.mpi
@pytest.mark.parametrize("rule", ["exact", 6])
def test_split_residual_and_jacobian_are_the_whole_forms_two_ranks(make_config, monkeypatch, rule):
    assert MPI.COMM_WORLD.size == 2
    check_split_jacobian(MPI.COMM_WORLD, make_config, monkeypatch, rule)


def test_varying_rows_are_the_contact_rows(make_config, monkeypatch):
    # N = 8, Γ_C = bottom: the exact rule touches the 9 rows of Γ_C's vertices; degree 6 (UFL's ds form)
    # the rows of every vertex of the 8 cells on Γ_C, the 9 and the 8 above them
    for rule, expected in (("exact", 9), (6, 17)):
        problem = solved_problem(make_config(contact_quadrature=rule, mesh={"refinements": [8]}), monkeypatch)
        newton = solver.NewtonSolver(problem.F, problem.J, problem.u_h, problem.bcs, {}, split=problem.split,
                                     contact=problem.contact)
        assert len(newton.K_rows.rows) == expected
        newton.destroy()


# --- the Γ_C terms assembled beside UFL ---------------------------------------------------------------

@pytest.mark.parametrize("alpha", [1.5, 2.0, 3.0])
@pytest.mark.parametrize("dimension", [2, 3])
def test_jacobian_is_the_derivative_of_the_residual(make_config, monkeypatch, alpha, dimension):
    cube = {"dimension": 3, "mesh": {"kind": "unit_cube", "refinements": [3]},
            "problem": {"exact": "sin(2*pi*x)*sin(pi*y)*(1-z)**2"}}
    square = {"mesh": {"refinements": [4]}}
    cfg = make_config(alpha=alpha, epsilon={"law": "constant", "theta": 1e-2}, **(cube if dimension == 3 else square))
    problem = solved_problem(cfg, monkeypatch)
    newton = solver.NewtonSolver(problem.F, problem.J, problem.u_h, problem.bcs, {}, split=problem.split,
                                 contact=problem.contact)
    newton.assemble_fixed()
    x, d = newton.x.duplicate(), newton.x.duplicate()
    n = x.getLocalSize()
    # vertex values of size >= 0.1 (away from the kink of psi at 0) and of either sign
    x.setArray(np.random.default_rng(3).uniform(0.1, 1.0, n) * np.sign(np.sin(np.arange(n) + 0.5)))
    fem_petsc.set_bc(x, problem.bcs)  # the solver's iterates satisfy the Dirichlet condition
    d.setArray(np.cos(np.arange(n)))
    fem_petsc.set_bc(d, problem.bcs, scale=0.0)
    delta = 1e-5
    F_plus, F_minus, Jd = newton.b.duplicate(), newton.b.duplicate(), newton.b.duplicate()
    newton.assemble_residual(x + delta * d, F_plus)
    newton.assemble_residual(x - delta * d, F_minus)
    newton.assemble_residual(x, newton.b)  # leaves x in u: the Jacobian's point
    newton.assemble_jacobian(newton.A)
    newton.A.mult(d, Jd)
    difference = (F_plus - F_minus) / (2 * delta)
    # central differences: truncation delta^2 |F'''| ~ 1e-10 |J d| (psi is smooth off its kink, and no
    # vertex value is near it) and round-off 1e-16 |F| / delta ~ 1e-11 |J d|
    assert (difference - Jd).norm() <= 1e-7 * Jd.norm()
    newton.destroy()


FIGURE = {"alpha": 1.0, "epsilon": {"law": "constant", "theta": 1e-8}, "mesh": {"refinements": [16, 64]}}


def test_default_settings_give_the_exactly_integrated_p1_solution(make_config):
    # 2-D, u_ex = sin(2 pi x)(1-y)^2, alpha = 1, eps = 1e-8, exact positive part, the contact term
    # integrated exactly: L2 = 5.800452e-3 (N = 16) and 4.055548e-4 (N = 64) from scikit-fem and NGSolve
    # (agreeing to 5e-12); 1e-6 relative is the issue's requirement (the figures' 7 digits)
    levels = studies.run_study(make_config(**FIGURE), comm=MPI.COMM_SELF)
    assert all(level.outcome.converged for level in levels)
    assert levels[0].errors["L2"] == pytest.approx(5.800452e-3, rel=1e-6)
    assert levels[1].errors["L2"] == pytest.approx(4.055548e-4, rel=1e-6)
