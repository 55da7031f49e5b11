"""Observed rates from the measured h."""
import math

import pytest

from signorini_cli import rates


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
