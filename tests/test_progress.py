"""Progress lines: one per level, Newton steps of long levels only, the ETA from cost ~ dofs^p."""
import io

import pytest
import yaml

from signorini_cli import config, progress
from conftest import BASE, merge


def row(level, n, seconds, converged=True):
    return {"level": level, "N": n, "dofs": (n + 1) ** 2, "epsilon": 1.0 / n, "converged": converged,
            "newton_its": 6, "reason": "DIVERGED_MAX_IT", "L2": 1.0 / n**2 if converged else None,
            "rate_L2": 2.0 if converged and level else None, "time_s": seconds}


class Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def test_level_line_has_everything():
    line = progress.level_line(row(1, 16, 0.25))
    assert line == "level 1  N=16  dofs=289  eps=6.250e-02  newton 6  L2 3.906e-03 (rate 2.00)  0.25 s"


def test_level_line_not_converged():
    line = progress.level_line(row(2, 32, 12.5, converged=False))
    assert "NOT CONVERGED after 6 (DIVERGED_MAX_IT)" in line and "L2" not in line and line.endswith("12.5 s")


def test_cost_exponent_from_last_levels():
    dofs = [1e2, 1e3, 1e4, 1e5]
    assert progress.cost_exponent(dofs, [d**1.3 for d in dofs]) == pytest.approx(1.3)
    # coarse levels dominated by set-up look cheaper than linear: never extrapolate below linear
    assert progress.cost_exponent(dofs, [1.0, 1.1, 1.2, 1.3]) == progress.MIN_EXPONENT
    assert progress.cost_exponent(dofs[:1], [1.0]) == progress.MIN_EXPONENT


def test_remaining_time_extrapolates_in_dofs():
    rows = [row(0, 10, 1.0), row(1, 20, 4.0)]  # dofs ~ N^2 and time ~ N^2: p ≈ 1 in dofs
    eta = progress.remaining_time(rows, (40, 80), dim=2)
    exponent = progress.cost_exponent([121, 441], [1.0, 4.0])
    assert eta == pytest.approx(4.0 * (4**exponent + 16**exponent))
    assert progress.remaining_time(rows, (), dim=2) is None


class Config:
    class mesh:
        kind = "unit_square"
        refinements = levels = (8, 16, 32)
    dimension = 2


def test_newton_lines_only_after_threshold():
    out, clock = io.StringIO(), Clock()
    shown = progress.Progress(Config, stream=out, newton_after=3.0, clock=clock)
    clock.now = 1.0
    shown.monitor(None, 0, 1.0)  # a short level: nothing
    assert out.getvalue() == ""
    clock.now = 4.0
    shown.monitor(None, 2, 1e-6)
    assert out.getvalue() == "  level 0 (N=8): Newton iteration 2, |F| = 1.000e-06  (4.00 s)\n"
    shown.level_done([row(0, 8, 4.0)])
    assert out.getvalue().splitlines()[-1].startswith("level 0  N=8") and "left" in out.getvalue()


def test_hidden_progress_prints_nothing():
    out = io.StringIO()
    shown = progress.Progress(Config, show=False, stream=out, newton_after=0.0)
    shown.monitor(None, 1, 1.0)
    shown.level_done([row(0, 8, 1.0)])
    assert out.getvalue() == ""


@pytest.mark.parametrize("seconds, text", [(0.421, "0.42 s"), (12.34, "12.3 s"), (245, "4 min 05 s"),
                                           (7380, "2 h 03 min")])
def test_format_duration(seconds, text):
    assert progress.format_duration(seconds) == text


@pytest.mark.parametrize("mesh, expected", [
    pytest.param({"kind": "gmsh", "geometry": "half_disk", "sizes": [0.2, 0.1, 0.05]}, (400.0, 1600.0),
                 id="gmsh-sizes"),
    pytest.param({"kind": "gmsh", "geometry": "half_disk", "sizes": [0.2], "refine": "uniform",
                  "refinements": [0, 1, 3]}, (400.0, 6400.0), id="gmsh-nested"),
])
def test_levels_left_gmsh_predicts_cells(mesh, expected):
    raw = merge(BASE, {"contact": "contact"})
    raw["mesh"] = mesh
    cfg = config.loads(yaml.safe_dump(raw))
    # level 0 had 100 cells: 2-D cells grow as size^-2, or 4 times per refinement; N is cells: dimension 1
    assert progress.levels_left(cfg.mesh, [row(0, 100, 1.0)], 2) == (expected, 1)
