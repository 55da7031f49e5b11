"""A map's outputs: map.csv in its column order, the heat map's colours (fitted − proven, not covered
masked and grey), the line plot's curves, map.tex and a terminal summary within 120 columns."""
import csv

import numpy as np
import pytest

from signorini_cli.report import maps

pytestmark = pytest.mark.fast

VARIED = ("epsilon.theta", "alpha")


def row(theta, alpha, rate, proven, verdict, log=None):
    return {"epsilon.theta": theta, "alpha": alpha, "rate_L2": rate, "rate_L2_lo": rate - 0.05,
            "rate_L2_hi": rate + 0.05, "rate_L2_log": log, "proven_L2": proven,
            "verdict_L2": verdict, "L2": 1e-3, "converged": True, "newton_its": 12, "time_s": 0.5,
            "status": "complete"}


ROWS = [row(0.1, 1, 1.98, None, "not covered"), row(0.1, 2, 1.5, 2.0, "below"),
        row(10, 1, 2.01, None, "not covered"), row(10, 2, 2.4, 2.0, "exceeds", log=2.6)]


def test_map_csv_columns_in_order(tmp_path):
    maps.write(tmp_path, ROWS, VARIED, draw=False)
    with open(tmp_path / maps.MAP_FILE) as f:
        header = next(csv.reader(f))
    assert header == ["epsilon.theta", "alpha", "rate_L2", "rate_L2_lo", "rate_L2_hi", "rate_L2_log", "proven_L2",
                      "verdict_L2", "L2", "converged", "newton_its", "time_s", "status"]


def test_heat_map_colours_fitted_minus_proven():
    fig = maps.heat_map(ROWS, "L2", "epsilon.theta", "alpha", [])
    grid = fig.axes[0].images[0].get_array()
    # rows: alpha 1 (not covered: masked, drawn grey), alpha 2; columns: theta 0.1, 10
    assert grid.mask[0].all() and not grid.mask[1].any()
    assert np.allclose(grid[1].data, [1.5 - 2.0, 2.4 - 2.0], rtol=0, atol=1e-15)
    assert len(fig.axes[0].patches) == 2  # the grey cells
    norm = fig.axes[0].images[0].norm
    assert (norm.vmin, norm.vcenter, norm.vmax) == (-maps.SPAN, 0.0, maps.SPAN)  # centred at 0


def test_heat_map_panel_per_value_of_the_other_keys():
    rows = [dict(r, **{"epsilon.law": law}) for law in ("theta_h", "theta_sqrt_h") for r in ROWS]
    fig = maps.heat_map(rows, "L2", "epsilon.theta", "alpha", ["epsilon.law"])
    panels = [ax for ax in fig.axes if ax.images]
    assert [ax.get_title() for ax in panels] == [r"$\|u-u_h\|_{L^2}$, epsilon.law = theta_h",
                                                 r"$\|u-u_h\|_{L^2}$, epsilon.law = theta_sqrt_h"]  # norm, fixed key


def test_rate_lines_draw_the_log_corrected_fit_where_there_is_one():
    fig = maps.rate_lines(ROWS, "L2", "epsilon.theta", ["alpha"])
    lines = fig.axes[0].get_lines()
    # alpha 1: rate, proven (no log-corrected fit); alpha 2: rate, log-corrected (at theta 10 only), proven
    assert len(lines) == 5
    assert np.isnan(lines[3].get_ydata()[0]) and lines[3].get_ydata()[1] == 2.6


def test_summary_fits_the_terminal():
    rows = [dict(r, **{"solver.petsc_options.pc_factor_mat_solver_type": "superlu_dist" * 3}) for r in ROWS]
    text = maps.summary(rows, VARIED + ("solver.petsc_options.pc_factor_mat_solver_type",))
    assert max(map(len, text.splitlines())) <= maps.TERMINAL_WIDTH


def test_latex_table_fits_the_text_width():
    tex = maps.latex_table(ROWS, VARIED, ["L2"])
    assert r"\resizebox" not in tex and r"\label{tab:map}" in tex and tex.count(r"\begin{table}") == 1
    assert r"\begin{tabular}{rrrrl}" in tex and r"\toprule" in tex and r"\hline" not in tex
    body = [line for line in tex.splitlines() if line.endswith(r"\\") and "&" in line][2:]
    assert body[3] == r"10 & 2 & 2.40 & 2.00 & exc \\"
