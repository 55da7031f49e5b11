"""The Signorini limit: the manufactured u_S, the ε-sweep's model error, total-error tables, output."""
import csv
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml
from mpi4py import MPI

from signorini_cli import config, studies
from signorini_cli.app import cli
from signorini_cli.meshing import meshes
from signorini_cli.record import results
from conftest import BASE, U_SIGNORINI, merge

ROOT = Path(__file__).resolve().parents[2]
LIMIT_CONFIGS = sorted(ROOT.glob("configs/limit/*.yaml"))
SWEEP = {"study_type": "epsilon_sweep", "alpha": None, "epsilon": None,
         "problem": {"exact": U_SIGNORINI, "exact_solves": "signorini"},
         "mesh": {"refinements": [8]},
         "limit": {"alpha": [1, 2, 3], "epsilon": [1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6]}}
RTOL = 1e-8  # 2 ranks reproduce the serial numbers to 1e-8 relative


def sympy_solution(cfg):
    """u_S of a config as a sympy expression in x, y (independent of UFL's differentiation)."""
    import sympy
    x, y = sympy.symbols("x y", real=True)
    functions = {"sin": sympy.sin, "cos": sympy.cos, "exp": sympy.exp, "log": sympy.log,
                 "sqrt": sympy.sqrt, "abs": sympy.Abs, "tanh": sympy.tanh}
    return cfg.problem.exact({"x": x, "y": y}, functions), (x, y)


def gamma_c_quadrature_points(face, n=16, points=4):
    """Gauss points (exact to degree 7, above the solver's degree 6) on the n facets of a unit-square face."""
    axis, value = face
    ref, _ = np.polynomial.legendre.leggauss(points)
    along = ((np.arange(n)[:, None] + (ref[None, :] + 1) / 2) / n).ravel()
    xy = np.empty((2, along.size))
    xy[axis], xy[1 - axis] = value, along
    return xy


@pytest.mark.parametrize("path", LIMIT_CONFIGS, ids=[p.name for p in LIMIT_CONFIGS])
def test_signorini_data_complementarity_at_quadrature_points(path):
    import sympy
    cfg = config.load(path)
    assert cfg.problem.exact_solves == "signorini" and cfg.dimension == 2
    u_S, (x, y) = sympy_solution(cfg)
    axis, value = meshes.FACES_2D[cfg.contact]
    outward = -1.0 if value == 0.0 else 1.0
    dn_u_S = outward * sympy.diff(u_S, (x, y)[axis])
    xy = gamma_c_quadrature_points((axis, value))
    u = sympy.lambdify((x, y), u_S, "numpy")(*xy) * np.ones(xy.shape[1])
    dn_u = sympy.lambdify((x, y), dn_u_S, "numpy")(*xy) * np.ones(xy.shape[1])
    # u_S <= 0, ∂_n u_S <= 0, u_S ∂_n u_S = 0 at every point: exact zeros, by construction
    # (one factor vanishes identically on each side of x = 1/2), so no tolerance
    assert np.all(u <= 0.0) and np.all(dn_u <= 0.0) and np.all(u * dn_u == 0.0)
    # both parts are there: contact (u_S = 0, pressure −∂_n u_S > 0) on x < 1/2, free (u_S < 0) beyond
    assert np.count_nonzero((u == 0.0) & (dn_u < 0.0)) == np.count_nonzero(u < 0.0) == xy.shape[1] // 2


def sweep_config(tmp_path, **changes):
    raw = merge(BASE, dict(SWEEP, output={"dir": str(tmp_path / "results")}))
    return config.loads(yaml.safe_dump(merge(raw, changes)))


def run_sweep(tmp_path, comm=MPI.COMM_WORLD, **changes):
    cfg = sweep_config(tmp_path, **changes)
    sweep = studies.run_study(cfg, comm=comm)
    assert all(solve.outcome.converged for solve in sweep)
    return cfg, sweep


def test_sweep_decreases_monotonically_small_mesh(tmp_path):
    cfg, sweep = run_sweep(tmp_path)
    rows = studies.sweep.sweep_table(sweep)
    for alpha in cfg.limit.alpha:
        group = [row for row in rows if row["alpha"] == alpha]
        assert [row["epsilon"] for row in group] == list(cfg.limit.epsilon)
        for m in studies.sweep.MODEL_ERRORS:
            values = [row[m] for row in group]
            assert all(b < a for a, b in zip(values, values[1:])), (alpha, m, values)
    fitted = {row["alpha"]: row for row in studies.sweep.fitted_table(sweep, cfg.limit.fit_last)}
    # N=8, ε = 1e-4..1e-6: measured H1 slopes 0.99, 0.44, 0.25 for α = 1, 2, 3 (→ 1/α as ε → 0,
    # later for larger α: docs/limit.md); 0.05 = the α = 1 margin, the order in α is the finding
    assert fitted[1.0]["fit_H1"] == pytest.approx(1.0, abs=0.05)
    assert fitted[1.0]["fit_H1"] > fitted[2.0]["fit_H1"] > fitted[3.0]["fit_H1"] > 0


@pytest.mark.mpi
def test_sweep_two_ranks_match_one(tmp_path):
    comm = MPI.COMM_WORLD
    assert comm.size == 2
    _, parallel = run_sweep(tmp_path, comm=comm)  # writes nothing: tmp_path only names the output
    _, serial = run_sweep(tmp_path, comm=MPI.COMM_SELF)
    for p, s in zip(parallel.points, serial.points):
        assert (p.alpha, p.eps) == (s.alpha, s.eps)
        for m in studies.sweep.MODEL_ERRORS:
            assert p.differences[m] == pytest.approx(s.differences[m], rel=RTOL)


def test_sweep_writes_documented_tables(tmp_path, capsys):
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump(merge(BASE, dict(SWEEP, output={"dir": str(tmp_path / "out")}))))
    assert cli.main(["run", str(path)]) == cli.EXIT_OK
    assert "fitted:" in capsys.readouterr().out
    folder = tmp_path / "out" / "t"
    with open(folder / "sweep.csv") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == list(studies.sweep.SWEEP_COLUMNS)  # README: Results of the ε → 0 studies
    assert len(rows) == 3 * len(SWEEP["limit"]["epsilon"]) and rows[0]["rate_H1"] == "" and float(rows[1]["rate_H1"]) > 0
    with open(folder / "fitted.csv") as f:
        assert [row["alpha"] for row in csv.DictReader(f)] == ["1.0", "2.0", "3.0"]
    with open(folder / "reference.csv") as f:
        reference = list(csv.DictReader(f))
    assert list(reference[0])[:len(studies.level.LEADING_COLUMNS)] == list(studies.level.LEADING_COLUMNS)
    with h5py.File(folder / "study.h5") as h5:
        assert h5.attrs["study_type"] == "epsilon_sweep" and sorted(h5) == ["fitted", "reference", "table"]
        assert h5["table"].attrs["table"] == "sweep"  # the main table, named by its CSV file
    assert (folder / "model_error.png").stat().st_size > 10_000  # output.plots (default): the ε plot
    assert cli.main(["run", str(path)]) == cli.EXIT_BAD_INPUT  # results exist: --force needed
    assert not list(folder.glob(".*.tmp*"))


def test_total_error_writes_spec_tables(make_config):
    cfg = make_config(study_type="total_error", alpha=None, epsilon=None,
                      problem={"exact": U_SIGNORINI, "exact_solves": "signorini"},
                      limit={"alpha": [2], "exponent": [1, 2]})
    total = studies.run_study(cfg, on_level=lambda done: results.write(studies.study_of(cfg, done)))
    assert all(level.outcome.converged for level in total)
    assert list(total.studies) == ["alpha2-p1", "alpha2-p2", "signorini"]
    for name in total.studies:
        with open(cfg.output_dir / name / "rates.csv") as f:
            rows = list(csv.DictReader(f))
        assert list(rows[0])[:len(studies.level.LEADING_COLUMNS)] == list(studies.level.LEADING_COLUMNS) and len(rows) == 2
    h = [row["h"] for row in rows]
    with open(cfg.output_dir / "total.csv") as f:
        summary = {row["study"]: row for row in csv.DictReader(f)}
    assert summary["signorini"]["epsilon"] == "0.0" and summary["signorini"]["alpha"] == ""
    assert float(summary["alpha2-p2"]["epsilon"]) == pytest.approx(float(h[-1]) ** 2)

