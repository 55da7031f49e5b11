"""The contact pressure profile: the pressure table a refinement study records (Γ_C nodes, sorted along Γ_C,
p_h = (1/ε)[u_h]_+^α and the exact one) and the figure drawn from it, with Hertz's curve for a Hertz scene."""
import numpy as np
from mpi4py import MPI

from signorini_cli import studies
from signorini_cli.report import pressure


def test_scalar_profile_rows_and_figure(make_config, tmp_path):
    """u_ex = sin(2πx)(1 − y)² on y = 0: pressure_exact = (1/ε)[sin 2πx]_+^2 at the nodes x = k/N exactly; p_h
    is nonzero only where it is (the contact set x < 1/2)."""
    cfg = make_config(mesh={"refinements": [4, 8]})
    levels = studies.run_study(cfg, comm=MPI.COMM_SELF)
    named = studies.of(cfg.study_type).tables(cfg, levels)
    rows = named["pressure"]
    for lv in levels:
        mine = [r for r in rows if r["level"] == lv.index]
        x = np.array([r["x"] for r in mine])
        assert np.allclose(x, np.arange(lv.n + 1) / lv.n) and np.all(np.diff(x) > 0)
        exact = np.maximum(np.sin(2 * np.pi * x), 0) ** 2 / lv.eps
        assert np.allclose([r["pressure_exact"] for r in mine], exact, rtol=1e-12, atol=1e-12)
        p_h = np.array([r["pressure"] for r in mine])
        assert np.all(p_h >= 0) and np.all(p_h[x > 0.5] == 0) and np.any(p_h > 0)
    paths = pressure.write((rows, named["rates"]), tmp_path)
    assert [p.name for p in paths] == ["pressure.png", "pressure.pdf"] and all(p.stat().st_size for p in paths)


def test_hertz_curve_from_the_finest_row():
    """Without an exact pressure the curve is Hertz's p0 (1 − ((x − c)/a)²)^(1/2) of the finest level's row,
    centred on its contact set; in 3-D (column r) from r = 0."""
    profile = [{"level": 0, "x": x, "pressure": p} for x, p in ((-0.2, 0.0), (-0.1, 1.0), (0.3, 1.0), (0.4, 0.0))]
    rates = [{"level": 0, "N": 4, "half_width_hertz": 0.25, "peak_pressure_hertz": 2.0}]
    x, p = pressure.exact_curve(profile, rates, 0, "x")
    assert np.isclose(x[0], 0.1 - 0.25) and np.isclose(x[-1], 0.1 + 0.25) and np.isclose(max(p), 2.0)
    radial = [dict(level=0, r=abs(row["x"]), pressure=row["pressure"]) for row in profile]
    r, p = pressure.exact_curve(radial, rates, 0, "r")
    assert r[0] == 0 and np.isclose(r[-1], 0.25) and p[0] == 2.0 and p[-1] == 0
    assert pressure.exact_curve(profile, [{"level": 0, "N": 4}], 0, "x") is None
