"""scripts/stability.py's contact-rule sections (docs/stability.md, `make stiff`): gaps, h/ε classes and the
ε → 0 verdict computed from the runs' tables (here hand-made tables), and the runs themselves on small meshes."""
import runpy
import sys
from pathlib import Path

import pytest

SCRIPTS = Path(__file__).resolve().parents[2] / "scripts"
sys.path.insert(0, str(SCRIPTS))  # the page generators share scripts/provenance.py
stability = runpy.run_path(str(SCRIPTS / "stability.py"))


def level(n, eps, l2, converged=True, its=2):
    h = 1 / n
    return {"N": n, "h": h, "epsilon": h if eps == "h" else float(eps), "converged": converged, "L2": l2,
            "rate_L2": None, "newton_its": its, "penetration": 0.0}


def found_rules(gap_at_small_eps):
    """Tables of every case: the vertex and Gauss rules' L2 equal to the exact one's at ε = h and
    off by `gap_at_small_eps` (relative) at ε = 1e-14; elsewhere equal."""
    found = {}
    for dim, alpha in stability["RULE_CASES"]:
        for eps in stability["RULE_EPS"]:
            for rule in stability["RULES"]:
                off = gap_at_small_eps if rule != "exact" and eps == "1.0e-14" else 0.0
                found[(dim, alpha, eps, rule)] = [level(n, eps, 1e-2 / n**2 * (1 + off)) for n in (8, 16)]
    return found


def test_rule_gaps_by_h_over_eps():
    summary, failed = stability["gap_summary"](found_rules(0.25))
    assert failed == 0
    # ε = h falls in the first class (h/ε = 1), 1e-14 with h = 1/8, 1/16 in the last (h/ε ~ 1e13)
    assert "| 2-D, 1 | vertex | 0.0e+00 | 0.0e+00 | 2.5e-01 | 0 |" in summary
    assert "| 3-D, 2 | 6 | 0.0e+00 | 0.0e+00 | 2.5e-01 | 0 |" in summary


def test_rules_section_checks_the_independent_figures():
    found = found_rules(0.0)
    # the contact-rule comparison's figures at 2-D, α = 1, ε = 1e-8: 5.800452e-3 (N = 16), 4.055548e-4 (N = 64)
    found[(2, "1.0", "1.0e-8", "exact")] = [level(16, "1.0e-8", 5.800452e-3), level(64, "1.0e-8", 4.1e-4)]
    text = stability["rules_section"](found)
    assert "N = 16: 5.800452e-03 against 5.800452e-03 (relative difference 0.0e+00)" in text
    assert "(relative difference 1.1e-02)" in text  # |4.1e-4 - 4.055548e-4| / 4.055548e-4 = 1.096e-2


def sweep_tables(slope):
    """An ε-sweep's sweep and fitted tables for α = 1 on N = 16: L2 difference 1e-3 ε^slope."""
    eps = [1e-2, 1e-8, 1e-14]
    rows = [{"alpha": 1.0, "N": 16, "epsilon": e, "converged": True, "L2": 1e-3 * (e / 1e-2) ** slope,
             "penetration": 0.0} for e in eps]
    return {"sweep": rows, "fitted": [{"alpha": 1.0, "N": 16, "fit_L2": slope}]}


def test_limit_verdict_from_the_fitted_slope():
    found = {(2, "exact"): sweep_tables(1.0), (2, "6"): sweep_tables(0.05)}
    summary, verdict = stability["limit_summary"](found)
    # slope 1: the difference falls 12 decades; slope 0.05 (< TENDS_SLOPE = 0.1): it has stalled
    assert verdict == {"exact": [True], "6": [False]}
    assert "| 2 | 1 | 16 | exact | 1.000e-03 | 1.000e-15 | 1.0e-12 | 1.00 |" in summary


def test_rule_runs_small(tmp_path):
    found = stability["rule_runs"](stability["Runs"](tmp_path), cases=((2, "2.0"),), eps_values=("h", "1.0e-8"),
                                   levels={2: "[4, 8]"})
    assert len(found) == 2 * len(stability["RULES"])
    assert all(r["converged"] for rows in found.values() for r in rows)
