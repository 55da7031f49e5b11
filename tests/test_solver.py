"""Numerical faults: NaN or Inf in the residual, the Jacobian or the solution fail the level with a
reason, never an exception; the study then continues or stops per solver.on_failure."""
import csv

import pytest
import yaml

from signorini_cli import cli, solver, study
from conftest import BASE, merge

NAN_DATA = {"exact": None, "f": "sqrt(x - 0.5)"}  # NaN at every quadrature point with x < 0.5
INF_DATA = {"exact": None, "f": "exp(1000*x)"}  # overflows to Inf for x > 0.71


@pytest.mark.parametrize("problem", [pytest.param(NAN_DATA, id="nan"), pytest.param(INF_DATA, id="inf")])
@pytest.mark.parametrize("on_failure, levels", [("continue", 2), ("stop", 1)])
def test_nonfinite_data_fails_levels(make_config, problem, on_failure, levels):
    done = study.run_study(make_config(problem=problem, solver={"on_failure": on_failure}))
    assert len(done) == levels
    assert all(not lv.outcome.converged and lv.outcome.reason == "DIVERGED_FNORM_NAN" for lv in done)


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
    (level, _) = study.run_study(make_config())
    assert level.outcome.reason == "DIVERGED_FNORM_NAN" and level.outcome.newton_its >= 1


def test_nan_solution_with_finite_residual(make_config, monkeypatch):
    def spoil(x, F):
        x.array[0] = float("nan")  # the iterate itself, which the residual norm does not see
    patch_after(monkeypatch, "_residual", 3, spoil)
    (level, _) = study.run_study(make_config())
    assert not level.outcome.converged and level.outcome.reason == "DIVERGED_FNORM_NAN"


@pytest.mark.parametrize("linear", ["direct", "iterative"])
def test_nan_jacobian_fails_the_linear_solve(make_config, monkeypatch, linear):
    patch_after(monkeypatch, "_jacobian", 2, lambda x, J, P: J.scale(float("nan")))
    (level, _) = study.run_study(make_config(solver={"linear": linear}))
    assert not level.outcome.converged and level.outcome.reason == "DIVERGED_LINEAR_SOLVE"


def test_nonfinite_level_in_cli(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(merge(BASE, {"problem": NAN_DATA, "solver": {"on_failure": "stop"},
                                                "output": {"dir": str(tmp_path / "out"), "plots": False}})))
    assert cli.main(["run", str(path)]) == cli.EXIT_NOT_CONVERGED
    with open(tmp_path / "out" / "t" / "rates.csv") as f:
        (row,) = csv.DictReader(f)
    assert row["converged"] == "false" and row["reason"] == "DIVERGED_FNORM_NAN"
    assert (tmp_path / "out" / "t" / "status.txt").read_text() == "failed at level 0: DIVERGED_FNORM_NAN\n"
