"""The verdict per norm at its edges, the `expect:` block, and the summary's CSV and HDF5 forms."""
import csv
import io
import math

import h5py
import pytest

from signorini_cli.analysis import verdict
from signorini_cli.record import csvfile, h5 as record_h5, results
from signorini_cli.solve.solver import Outcome
from signorini_cli.studies import Level

pytestmark = pytest.mark.fast

H = [0.2, 0.1, 0.05, 0.025]


def levels(errors, extra=None, converged=None):
    """Synthetic levels: errors {norm: [value per level]}, extra {column: [value per level]}."""
    extra = extra or {}
    converged = converged or [True] * len(H)
    out = []
    for k, h in enumerate(H):
        reason = "CONVERGED_FNORM_ABS" if converged[k] else "DIVERGED_MAX_IT"
        outcome = Outcome(converged[k], reason, 5, 5, (1.0,))
        lv = Level(k, round(1 / h), h, 100, h, outcome, {n: v[k] for n, v in errors.items()}, 1.0)
        lv.extra.update({c: v[k] for c, v in extra.items()})
        out.append(lv)
    return out


@pytest.mark.parametrize("observed, proven, tolerance, expected", [
    pytest.param(1.9, 2.0, 0.1, verdict.AGREES, id="exactly-at-tolerance"),
    pytest.param(1.9 - 1e-9, 2.0, 0.1, verdict.BELOW, id="just-below"),
    pytest.param(2.6, 2.0, 0.1, verdict.AGREES, id="above-proven"),
    pytest.param(2.0, 2.0, 0.0, verdict.AGREES, id="zero-tolerance"),
    pytest.param(1.5, None, 0.1, verdict.NOT_COVERED, id="not-covered"),
    pytest.param(None, 2.0, 0.1, verdict.NO_RATE, id="no-rate"),
    pytest.param(None, None, 0.1, verdict.NOT_COVERED, id="neither"),
])
def test_decide_edges(observed, proven, tolerance, expected):
    assert verdict.decide(observed, proven, tolerance) == expected


def test_summarize_fits_and_judges(make_config):
    cfg = make_config()  # 2-D, alpha = 2, eps = h: L2 proven 2, H1 proven 1
    lv = levels({"L2": [h**2 for h in H], "H1": [0.5 * h**0.8 for h in H]})
    by_norm = {v.norm: v for v in verdict.summarize(cfg, lv).norms}
    assert by_norm["L2"].observed == pytest.approx(2) and by_norm["L2"].verdict == verdict.AGREES
    assert by_norm["H1"].observed == pytest.approx(0.8) and by_norm["H1"].verdict == verdict.BELOW
    assert by_norm["L2"].levels == (10, 20, 40)  # the last fit_levels = 3 levels


def test_singular_scene_is_not_covered_rather_than_below(make_config):
    # the L-shape's corner: rates of a singular u (here 0.67) are no failure of the method
    cfg = make_config(verification={"regular": False})
    lv = levels({"L2": [h**1.33 for h in H], "H1": [h**0.67 for h in H]})
    by_norm = {v.norm: v for v in verdict.summarize(cfg, lv).norms}
    assert by_norm["H1"].verdict == by_norm["L2"].verdict == verdict.NOT_COVERED
    assert "W^{2,alpha+1}" in by_norm["H1"].conditions and by_norm["H1"].observed == pytest.approx(0.67)


def test_summarize_log_factor_case(make_config):
    cfg = make_config(alpha=3.0)  # Lemma 4.5: O(h^2 |ln h|); an error of exactly that size agrees
    lv = levels({"L2": [0.9 * h**1.95 * -math.log(h) for h in H]})
    (l2,) = verdict.summarize(cfg, lv).norms
    assert l2.log_factor and l2.observed == pytest.approx(1.95) and l2.plain < l2.observed
    assert l2.verdict == verdict.AGREES


def test_summarize_not_covered_alpha1(make_config):
    cfg = make_config(alpha=1.0)
    (l2,) = verdict.summarize(cfg, levels({"L2": [h**2 for h in H]})).norms
    assert l2.verdict == verdict.NOT_COVERED and "alpha > 1" in l2.conditions


def test_successive_differences_not_covered_when_eps_moves(make_config):
    data = {"problem": {"exact": None, "f": "10"}}
    diffs = {"diff_L2": [None] + [h**2 for h in H[1:]]}
    extra = {"diff_L2": diffs["diff_L2"], "rate_diff_L2": [None] * 4}
    moving = verdict.summarize(make_config(**data), levels(diffs, extra)).norms[0]
    fixed = verdict.summarize(make_config(epsilon={"law": "constant", "theta": 0.1}, **data),
                              levels(diffs, extra)).norms[0]
    assert moving.verdict == verdict.NOT_COVERED and "different eps" in moving.conditions
    assert fixed.verdict == verdict.AGREES and fixed.proven == 2


def test_expect_met_and_missed(make_config):
    lv = levels({"L2": [h**2 for h in H], "H1": [h for h in H]})
    met = verdict.summarize(make_config(expect={"rates": {"L2": 2.0, "H1": 1.0}}), lv)
    assert met.met and all(e.met for e in met.expectations)
    missed = verdict.summarize(make_config(expect={"rates": {"L2": 2.5}, "tolerance": 0.2}), lv)
    assert not missed.met and "expect L2 >= 2.5 - 0.2: NOT MET (observed 2.00)" in verdict.format_summary(missed)
    absent = verdict.summarize(make_config(expect={"rates": {"energy_err": 1.0}}), lv)
    assert not absent.met  # a rate the study did not measure is not met


def test_quantities_get_gci_for_data_only_scenes(make_config):
    cfg = make_config(problem={"exact": None, "f": "10"})
    force = [2.0 - 0.3 * h**2 for h in H]
    lv = levels({}, {"contact_force": force, "penetration": [0.1] * 4})
    quantities = {q.quantity: q for q in verdict.summarize(cfg, lv).quantities}
    assert quantities["contact_force"].estimate.order == pytest.approx(2)
    assert quantities["contact_force"].estimate.extrapolated == pytest.approx(2.0)
    assert quantities["penetration"].estimate is None  # constant: no order to observe
    assert "no order observable" in verdict.format_summary(verdict.summarize(cfg, lv))


def test_summary_csv_and_h5(make_config, tmp_path):
    cfg = make_config(expect={"rates": {"L2": 2.0}})
    summary = verdict.summarize(cfg, levels({"L2": [h**2 for h in H], "H1": [h for h in H]}))
    rows = list(csv.DictReader(io.StringIO(csvfile.text(verdict.summary_rows(summary), verdict.SUMMARY_COLUMNS))))
    assert [(r["kind"], r["name"], r["verdict"]) for r in rows] == [
        ("norm", "L2", "agrees"), ("norm", "H1", "agrees"), ("expect", "L2", "")]
    assert float(rows[0]["proven_rate"]) == 2 and rows[0]["paper"] == "Lemma 4.2" and rows[2]["met"] == "true"
    record_h5.write(tmp_path / "s.h5", {}, {}, summary_rows=results.summary_record(summary))
    with h5py.File(tmp_path / "s.h5") as h5:
        assert h5["verification/norm/L2"].attrs["verdict"] == "agrees"
        assert h5["verification"].attrs["expectations_met"]
