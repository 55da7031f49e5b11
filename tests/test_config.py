"""Config validation: defaults, the epsilon laws, and rejections that name their key."""
import pytest
import yaml

from signorini_cli import config
from conftest import BASE, merge


def load(changes):
    return config.loads(yaml.safe_dump(merge(BASE, changes)))


def test_defaults_filled_in():
    cfg = load({})
    assert cfg.positive_part.kind == "exact"
    assert cfg.solver.linear == "auto" and cfg.solver.on_failure == "continue"
    assert cfg.mesh.refinements == (4, 8) and cfg.output.dir == "results"
    assert str(cfg.output_dir) == "results/t"


@pytest.mark.parametrize("law, expected", [
    ("theta_h", 2.0 * 0.25), ("theta_sqrt_h", 2.0 * 0.5), ("constant", 2.0),
])
def test_epsilon_laws(law, expected):
    assert load({"epsilon": {"law": law, "theta": 2.0}}).epsilon(0.25) == pytest.approx(expected)


def test_epsilon_power_law():
    eps = load({"epsilon": {"law": "power", "theta": 3.0, "exponent": 1.5}}).epsilon
    assert eps(0.25) == pytest.approx(3.0 * 0.25**1.5)


def test_positive_part_smooth_default_delta():
    cfg = load({"positive_part": "smooth"})
    assert cfg.positive_part.kind == "smooth" and cfg.positive_part.delta.text == "1e-2*h**2"


def test_override_applies_before_validation():
    cfg = config.loads(yaml.safe_dump(BASE), ["epsilon.theta=10", "solver.max_it=7"])
    assert cfg.epsilon.theta == 10.0 and cfg.solver.max_it == 7
    with pytest.raises(config.ConfigError, match=r"^epsilon.theta: must be > 0, got -1"):
        config.loads(yaml.safe_dump(BASE), ["epsilon.theta=-1"])


@pytest.mark.parametrize("changes, message", [
    pytest.param({"epsilon": {"theta": -1}}, "epsilon.theta: must be > 0, got -1", id="theta-negative"),
    pytest.param({"epsilon": {"law": "thetah"}}, "epsilon.law: 'thetah' is not one of", id="law"),
    pytest.param({"epsilon": {"exponent": 2}}, "epsilon.exponent: only meaningful with law: power", id="exponent"),
    pytest.param({"alpha": 0.5}, "alpha: must be >= 1, got 0.5", id="alpha-low"),
    pytest.param({"alpha": "two"}, "alpha: must be a number, got str 'two'", id="alpha-type"),
    pytest.param({"dimension": 4}, "dimension: must be 2 or 3, got 4", id="dimension"),
    pytest.param({"dimension": 3}, "mesh.kind: unit_square is 2-D but dimension is 3", id="kind-dim"),
    pytest.param({"dimension": 3, "alpha": 4, "mesh": {"kind": "unit_cube"}},
                 r"alpha: must be <= 3 in 3-D \(the paper's condition \(5\)\)", id="alpha-3d"),
    pytest.param({"mesh": {"refinements": [8, 4]}}, r"mesh.refinements: must increase", id="decreasing"),
    pytest.param({"mesh": {"refinements": []}}, "mesh.refinements: must be a non-empty list", id="empty"),
    pytest.param({"mesh": {"refinements": [4, 8.5]}}, r"mesh.refinements\[1\]: must be an integer", id="float-n"),
    pytest.param({"mesh": {"kind": "disk"}}, "mesh.kind: 'disk' is not one of", id="kind"),
    pytest.param({"contact": "front"}, "contact: 'front' is not one of left, right, bottom, top", id="face-2d"),
    pytest.param({"alpah": 2}, "alpah: unknown key in config \\(did you mean 'alpha'\\?\\)", id="typo"),
    pytest.param({"epsilon": {"thetta": 1}}, "epsilon.thetta: unknown key in epsilon \\(did you mean 'theta'", id="typo-nested"),
    pytest.param({"study": None}, "study: missing required key", id="missing"),
    pytest.param({"problem": {"exact": "z*x"}}, "problem.exact: unknown name 'z'", id="z-in-2d"),
    pytest.param({"problem": {"exact": "__import__('os')"}}, "problem.exact: unknown function", id="injection"),
    pytest.param({"problem": {"exact": None, "g": "x"}}, "problem: give exact", id="no-exact-no-f"),
    pytest.param({"problem": {"f": "1"}}, "problem: exact determines f and g", id="exact-and-f"),
    pytest.param({"positive_part": "soft"}, "positive_part.kind: 'soft' is not one of exact, smooth", id="pp"),
    pytest.param({"positive_part": {"kind": "exact", "delta": 1}}, "positive_part.delta: only meaningful", id="pp-delta"),
    pytest.param({"solver": {"linear": "gmres"}}, "solver.linear: 'gmres' is not one of", id="linear"),
    pytest.param({"solver": {"max_it": 0}}, "solver.max_it: must be >= 1, got 0", id="max-it"),
    pytest.param({"study": "a/b"}, "study: must be a plain folder name", id="study-path"),
])
def test_rejection_names_key(changes, message):
    with pytest.raises(config.ConfigError, match="^" + message):
        load(changes)


def test_not_a_mapping():
    with pytest.raises(config.ConfigError, match="must be a YAML mapping"):
        config.loads("- a\n- b\n")


def test_load_keeps_text(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(BASE))
    assert config.load(path).text == path.read_text()


def test_output_report_keys():
    assert load({}).output == config.Output(dir="results", plots=True, fields=False, digits=3)
    cfg = load({"output": {"plots": False, "fields": True, "digits": 5}})
    assert (cfg.output.plots, cfg.output.fields, cfg.output.digits) == (False, True, 5)
    with pytest.raises(config.ConfigError, match=r"^output.digits: must be >= 1, got 0"):
        load({"output": {"digits": 0}})
    with pytest.raises(config.ConfigError, match=r"^output.fields: must be true or false, got str 'yes'"):
        load({"output": {"fields": "yes"}})


@pytest.mark.parametrize("changes", [
    pytest.param({}, id="defaults"),
    pytest.param({"epsilon": {"law": "power", "exponent": 1.5}, "positive_part": "smooth",
                  "solver": {"petsc_options": {"ksp_view": None}}}, id="power-smooth-options"),
    pytest.param({"problem": {"exact": None, "f": "-10"}}, id="data-only"),
])
def test_to_dict_round_trip(changes):
    resolved = config.to_dict(load(changes))
    assert config.to_dict(config.from_dict(resolved)) == resolved
    assert list(resolved)[:2] == ["study", "description"] and "text" not in resolved
