"""Progress lines: one per level, Newton steps of long levels only, the time left from cost ~ dofs^p once\nit can be honest."""
import io

import pytest
import yaml

from signorini_cli import config
from signorini_cli.report import progress
from conftest import BASE, merge

pytestmark = pytest.mark.fast


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
    assert progress.cost_exponent(dofs, [d**3 for d in dofs]) == progress.MAX_EXPONENT
    assert progress.cost_exponent(dofs[:1], [1.0]) == progress.MIN_EXPONENT


def test_remaining_time_extrapolates_in_dofs():
    # level 0 is left out (one-off costs); the floor is level 1's 1 s, level 2 (4 s) is above 3x it,
    # so it alone sets the scale, with p = 1 (MIN_EXPONENT)
    rows = [row(0, 10, 9.0), row(1, 20, 1.0), row(2, 40, 4.0)]
    eta = progress.remaining_time(rows, (80,), dim=2)
    assert eta == pytest.approx(4.0 * 4)  # dofs of N = 80 estimated as 41^2 (80/40)^2: 4 times level 2's
    assert progress.remaining_time(rows, (), dim=2) is None


def test_no_estimate_from_compile_time_or_the_set_up_floor():
    # level 0: 40 s of form compilation (t_forms), then levels that cost the same fixed set-up time
    rows = [dict(row(0, 8, 40.5), t_forms=40.0), row(1, 16, 0.1), dict(row(2, 32, 0.12), t_forms=0.01)]
    assert progress.remaining_time(rows, (64, 128), dim=2) is None


# Recorded level times (s), each level's form compilation taken out: bench/results.csv (runs square-cold,
# cube, square-direct, square-iterative; t_forms subtracted) and `signorini run configs/demo.yaml` with
# N = 8..512 (its progress lines). dofs per level, then seconds.
RECORDED = {
    "square-cold": ([4225, 16641, 66049, 263169, 1050625], [0.074, 0.324, 0.950, 4.962, 22.500]),
    "cube": ([729, 4913, 35937, 274625], [0.041, 0.170, 1.249, 11.275]),
    "square-direct": ([4225, 16641, 66049, 263169], [0.072, 0.196, 0.840, 4.291]),
    "square-iterative": ([4225, 16641, 66049, 263169], [0.062, 0.105, 0.396, 1.635]),
    "demo": ([81, 289, 1089, 4225, 16641, 66049, 263169], [0.03, 0.03, 0.04, 0.07, 0.33, 0.50, 2.52]),
}


@pytest.mark.parametrize("name", RECORDED)
def test_estimates_within_3x_of_the_time_really_left(name):
    dofs, seconds = RECORDED[name]
    rows = [dict(row(k, 2**k, t), dofs=d) for k, (d, t) in enumerate(zip(dofs, seconds))]
    shown = 0
    for k in range(1, len(rows) - 1):
        done = rows[:k + 1]
        n_left = [done[-1]["N"] * (d / done[-1]["dofs"]) ** 0.5 for d in dofs[k + 1:]]  # exact dofs back
        eta = progress.remaining_time(done, n_left, dim=2)
        if eta is not None:
            truth = sum(seconds[k + 1:])
            assert truth / 3 <= eta <= 3 * truth, f"after level {k}: {eta:.2f} s estimated, {truth:.2f} s left"
            shown += 1
    assert shown >= 1  # and some estimate before the last level


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
    assert out.getvalue().splitlines()[-1].startswith("level 0  N=8") and "left" not in out.getvalue()


def test_time_left_wraps_at_120_columns():
    """N = 1024 with a time left in hours: the estimate goes below the level's line, each within 120 columns."""
    line = progress.level_line(dict(row(4, 1024, 245.0), newton_its=12, H1=3.5e-3, rate_H1=1.0))
    shown = progress.with_time_left(line, 7380.0).splitlines()
    assert shown == [line, "  ~2 h 03 min left"] and all(len(text) <= 120 for text in shown)
    short = progress.level_line(row(1, 16, 0.25))
    assert progress.with_time_left(short, 2.5) == short + "  ~2.50 s left"
    assert progress.with_time_left(short, None) == short


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
