"""The element section: degree 1 or 2, and what P2 refuses as bad input (one line, the key named)."""
import pytest

from signorini_cli import config
from conftest import U_SIGNORINI

pytestmark = pytest.mark.fast


def test_default_is_p1_with_the_exact_contact_rule(make_config):
    cfg = make_config()
    assert cfg.element.degree == 1 and cfg.contact_quadrature == "exact"


def test_p2_takes_the_exact_rule_by_default(make_config):
    cfg = make_config(element={"degree": 2})
    assert cfg.contact_quadrature == "exact"
    assert config.fingerprint(config.from_dict(config.to_dict(cfg))) == config.fingerprint(cfg)  # reads back
    assert make_config(element={"degree": 2}, contact_quadrature=12).contact_quadrature == 12


@pytest.mark.parametrize("changes, path, message", [
    ({"element": {"degree": 3}}, "element.degree", "must be <= 2, got 3"),
    ({"element": {"degree": True}}, "element.degree", "must be an integer, got bool True"),
    ({"element": {"order": 2}}, "element.order", "unknown"),
    ({"element": {"degree": 2}, "contact_quadrature": "vertex"}, "contact_quadrature", "lumps P1 only"),
    ({"element": {"degree": 2}, "output": {"fields": True}}, "output.fields", "element.degree 1 only"),
    ({"element": {"degree": 2}, "study_type": "signorini", "alpha": None, "epsilon": None,
      "problem": {"exact": U_SIGNORINI, "exact_solves": "signorini"}}, "element.degree", "P1 only"),
])
def test_bad_element_input(make_config, changes, path, message):
    with pytest.raises(config.ConfigError) as err:
        make_config(**changes)
    assert err.value.path == path and message in str(err.value)
