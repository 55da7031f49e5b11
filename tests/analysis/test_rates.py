"""Rates: observed from the measured h, fitted over the last levels, proven by the paper, and the GCI."""
import math
import re
from pathlib import Path

import numpy as np
import pytest

from signorini_cli.analysis import rates

pytestmark = pytest.mark.fast


def test_observed_exact_power_law():
    h = [0.5, 0.25, 0.1]
    assert rates.observed(h, [x**2 for x in h], [True] * 3) == [None, pytest.approx(2), pytest.approx(2)]


def test_observed_skips_failed_level():
    h = [0.4, 0.2, 0.1]
    obs = rates.observed(h, [0.16, 99.0, 0.01], [True, False, True])
    assert obs[:2] == [None, None]
    assert obs[2] == pytest.approx(math.log(16) / math.log(4))


def test_observed_uses_real_h_not_halving():
    assert rates.observed([0.3, 0.1], [0.09, 0.01], [True, True])[1] == pytest.approx(2)


# --- fitted slopes --------------------------------------------------------------------------------

def test_fitted_recovers_slope_of_last_levels():
    h = [0.5, 0.25, 0.125, 0.0625, 0.03125]
    e = [1.0, 0.9] + [3.0 * x**1.5 for x in h[2:]]  # pre-asymptotic first levels, then exactly h^1.5
    assert rates.fitted(h, e, [True] * 5, k=3) == pytest.approx(1.5, rel=1e-12)
    assert abs(rates.fitted(h, e, [True] * 5, k=5) - 1.5) > 0.1  # all five levels: the first ones distort it


def test_fitted_least_squares_of_noisy_data():
    h = [0.4, 0.2, 0.1, 0.05]
    noise = [1.05, 0.95, 1.05, 0.95]  # ±5 %: the fit averages it, successive rates would not
    e = [x**2 * n for x, n in zip(h, noise)]
    # by hand: log h is equally spaced (step -ln 2, centred indices -3/2 .. 3/2, sum of squares 5), so the
    # least-squares slope is 2 + (sum_k (k - 3/2) ln noise_k) / (5 (-ln 2)) = 2 + ln(1.05/0.95) / (5 ln 2)
    expected = 2 + np.log(1.05 / 0.95) / (5 * np.log(2))
    assert rates.fitted(h, e, [True] * 4, k=4) == pytest.approx(expected, rel=1e-12)


def test_fitted_skips_failed_and_needs_two_levels():
    h = [0.4, 0.2, 0.1]
    assert rates.fitted(h, [0.16, 99.0, 0.01], [True, False, True]) == pytest.approx(2)
    assert rates.fitted(h, [0.16, None, None], [True, True, True]) is None


def test_fitted_log_factor_reaches_two_on_h2_ln_h():
    h = [2.0**-k for k in range(4, 9)]
    e = [x**2 * -math.log(x) for x in h]  # the bound of Lemma 4.5, exactly
    assert rates.fitted(h, e, [True] * 5, log_factor=True) == pytest.approx(2, rel=1e-12)
    assert rates.fitted(h, e, [True] * 5) < 1.9  # the plain slope sits under 2, as the paper warns


def test_slope_fits_the_last_k_positive_points():
    x = [1.0, 2.0, 4.0, 8.0]
    assert rates.slope(x, [1.0, 1.0, 4.0, 8.0], k=2) == pytest.approx(1.0, rel=1e-12)
    assert rates.slope(x, [1.0, 1.0, 4.0, 8.0], k=3) == pytest.approx(1.5, rel=1e-12)  # slopes 2 then 1
    assert rates.slope(x, [1.0, None, 0.0, 8.0]) == pytest.approx(1.0, rel=1e-12)  # only (1, 1) and (8, 8)
    assert rates.slope([1.0], [1.0]) is None and rates.slope([2.0, 2.0], [1.0, 3.0]) is None


def test_default_fit_levels_is_the_configs():
    from signorini_cli.config import schema
    assert schema.Verification().fit_levels == rates.FIT_LEVELS


ROOT = Path(__file__).resolve().parents[2]
# a least-squares fit, a quotient of two logarithms (a rate between two levels), differences of logarithms
OTHER_FIT = re.compile(r"polyfit|lstsq|linregress|log\w*\([^()]*(\([^()]*\))?[^()]*\)\s*/\s*\(?\s*(np\.|math\.)?log|"
                       r"diff\(\s*(np\.)?log")


def test_one_rate_fit_in_the_package_and_its_scripts():
    # every rate (errors in h, model errors in eps, costs in dofs) goes through analysis/rates.py
    sources = sorted((ROOT / "signorini_cli").rglob("*.py")) + sorted((ROOT / "scripts").glob("*.py"))
    found = [f"{path.relative_to(ROOT)}:{k}" for path in sources if path.name != "rates.py" or path.parent.name !=
             "analysis" for k, line in enumerate(path.read_text().splitlines(), 1) if OTHER_FIT.search(line)]
    assert not found


def test_the_scan_sees_the_usual_forms():
    for line in ("p = np.polyfit(np.log(h), np.log(e), 1)[0]", "math.log(e0 / e1) / math.log(h0 / h1)",
                 "np.diff(np.log(e)) / np.diff(np.log(h))", "np.log(e[1:]/e[:-1]) / np.log(h[1:]/h[:-1])"):
        assert OTHER_FIT.search(line), line


# --- the paper's table ----------------------------------------------------------------------------
# what the paper proves, case by case: (d, alpha, eps exponent p in eps = theta h^p, norm) -> rate
SPEC_ROWS = [
    pytest.param(2, 2.0, 1.0, "H1", 1.0, False, id="any-alpha-h1-2d"),
    pytest.param(3, 3.0, 1.0, "H1", 1.0, False, id="any-alpha-h1-3d"),
    pytest.param(2, 5.0, 0.0, "H1", 1.0, False, id="h1-eps-constant"),
    pytest.param(2, 2.0, 1.0, "pos_gc_scaled", 1.5, False, id="eps-h-gamma-c"),
    pytest.param(3, 1.0, 1.0, "pos_gc_scaled", 1.5, False, id="eps-h-gamma-c-3d"),
    pytest.param(2, 2.0, 1.0, "L2", 2.0, False, id="2d-alpha2-theta-h"),
    pytest.param(3, 2.0, 1.0, "L2", 1.6, False, id="3d-alpha2-theta-h"),
    pytest.param(3, 2.0, 0.5, "L2", 2.0, False, id="3d-alpha2-theta-sqrt-h"),
    pytest.param(2, 3.0, 1.0, "L2", 2.0, True, id="2d-alpha3-log"),
    pytest.param(2, 4.0, 1.0, "L2", 2.0, True, id="2d-alpha4-log"),
    pytest.param(2, 1.0, 1.0, "H1", 1.0, False, id="alpha1-h1"),
    # consequences the table's rows imply
    pytest.param(2, 3.0, 1.0, "pos_gc", 0.75, False, id="pos-gc-root"),
    pytest.param(2, 2.0, 1.0, "energy_err", 1.0, False, id="lemma-3.1"),
    pytest.param(2, 2.0, 1.0, "L2_ref", 2.0, False, id="against-reference"),
    pytest.param(2, 2.0, 0.0, "diff_H1", 1.0, False, id="successive-difference"),
]


@pytest.mark.parametrize("d, alpha, p, norm, rate, log_factor", SPEC_ROWS)
def test_expected_matches_spec(d, alpha, p, norm, rate, log_factor):
    found = rates.expected(d, alpha, p, norm)
    assert found.rate == pytest.approx(rate) and found.log_factor == log_factor
    assert found.reference  # every proven rate names its lemma or corollary


@pytest.mark.parametrize("d, alpha, p, norm, reason", [
    pytest.param(2, 1.0, 1.0, "L2", "needs alpha > 1", id="alpha1-l2"),
    pytest.param(3, 1.0, 1.0, "L2", "needs alpha > 1", id="alpha1-l2-3d"),
    pytest.param(2, 2.0, 2.0, "H1", "outside the paper's hypotheses", id="eps-below-h"),
    pytest.param(3, 2.0, 0.5, "pos_gc_scaled", "eps ~ h", id="gamma-c-needs-eps-h"),
    pytest.param(3, 1.5, 1.0, "L2", "proves no rate", id="3d-alpha-not-2"),
    pytest.param(2, 1.5, 1.0, "L2", "proves no rate", id="2d-alpha-between"),
    pytest.param(3, 3.5, 1.0, "H1", "condition (5)", id="alpha-outside-5"),
    pytest.param(2, 2.0, 1.0, "L2_gc", "proves no rate", id="l2-gamma-c"),
])
def test_expected_not_covered(d, alpha, p, norm, reason):
    found = rates.expected(d, alpha, p, norm)
    assert found.rate is None and reason in found.reason


@pytest.mark.parametrize("record", [r for r in rates.PAPER_RATES if r.rate is not None],
                         ids=lambda r: f"{r.norm}-{r.reference}")
def test_every_paper_rate_is_reachable(record):
    """No dead record: some (d, alpha, p) inside the record's own conditions returns it (or a better one)."""
    alphas = {"any alpha": 2.0, "alpha = 1": 1.0, "alpha = 2": 2.0, "alpha > 2": 3.0}
    exponents = [p for p in (1.0, 0.5, 0.0) if rates.EPS_CONDITIONS[record.eps](p)]
    alpha = alphas[record.alpha]
    found = [rates.expected(d, alpha, p, record.norm) for d in record.dimensions for p in exponents]
    assert any(e.rate is not None and e.rate >= rates.rate_value(record, alpha) for e in found)
    assert any(e.reference == record.reference for e in found)


# --- grid convergence index -----------------------------------------------------------------------

@pytest.mark.parametrize("h", [pytest.param([0.4, 0.2, 0.1], id="ratio-2"),
                               pytest.param([0.3, 0.2, 0.1], id="ratio-varies")])
def test_grid_convergence_known_order(h):
    phi = [3.0 + 0.5 * x**2 for x in h]  # phi(h) = phi_0 + C h^2: order 2, limit 3
    g = rates.grid_convergence(h, phi)
    assert g.order == pytest.approx(2, rel=1e-9) and g.extrapolated == pytest.approx(3.0, rel=1e-12)
    r21 = h[1] / h[2]
    assert g.band == pytest.approx(1.25 * abs(phi[1] - phi[2]) / (r21**2 - 1), rel=1e-9)
    assert g.gci == pytest.approx(g.band / phi[2]) and not g.oscillatory
    assert abs(g.value - 3.0) < g.band  # the band covers the true error (here 0.5 h^2 = 0.005)


def test_grid_convergence_oscillatory_and_flat():
    g = rates.grid_convergence([0.4, 0.2, 0.1], [1.0 + 0.16, 1.0 - 0.04, 1.0 + 0.01])
    assert g.oscillatory and g.order == pytest.approx(2, rel=1e-9)  # |changes| shrink 4x per halving
    assert rates.grid_convergence([0.4, 0.2, 0.1], [1.0, 1.0, 1.0]) is None
