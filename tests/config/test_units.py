"""The config asks each problem, contact method and study type for its keys and rules (config/units.py): no
module of config/ compares a unit's name, every registered unit has the interface units.py states, and the cut
of the config into modules left every shipped config resolving and hashing as before."""
import ast
import dataclasses
import hashlib
import json
import subprocess
import sys
import types
from pathlib import Path

import pytest
import yaml

from signorini_cli import config
from signorini_cli.config import schema, units
from signorini_cli.config import validators as check
from conftest import BASE, merge

pytestmark = pytest.mark.fast

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "signorini_cli" / "config"
NAMES = set(units.PDES) | set(units.METHODS) | set(units.STUDY_TYPES)
# what units.py's docstring says each kind of unit has
INTERFACE = {"problem.pde": ("NAME", "DOC", "KEYS", "SECTION", "DEGREES", "VECTOR", "VI",
                             "problem", "check_config"),
             "problem.method": ("NAME", "DOC", "PDES", "SECTION", "UNUSED", "check_config"),
             "study_type": ("NAME", "DOC", "POINTS", "VI", "LIMIT_ERROR", "GEOMETRY", "FIELDS", "DEGREES", "UNUSED", "LIMIT",
                            "SECTION", "check_config")}


def load(changes):
    return config.loads(yaml.safe_dump(merge(BASE, changes)))


def compared_names(path):
    """(line, name) of each comparison (==, !=, in, not in) of a value with a unit's name in a module."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Compare):
            for operand in (node.left, *node.comparators):
                items = operand.elts if isinstance(operand, (ast.Tuple, ast.List, ast.Set)) else [operand]
                found += [(node.lineno, item.value) for item in items
                          if isinstance(item, ast.Constant) and item.value in NAMES]
    return found


def test_scan_finds_a_comparison_with_a_name(tmp_path):
    """The scan below is real: it finds the branches the config had before its rules were registered."""
    path = tmp_path / "branchy.py"
    path.write_text('if cfg.problem.pde == "elasticity" or kind in ("refinement", "map"):\n    pass\n')
    assert compared_names(path) == [(1, "elasticity"), (1, "refinement"), (1, "map")]


@pytest.mark.parametrize("path", sorted(CONFIG.glob("*.py")), ids=lambda p: p.name)
def test_config_never_compares_a_unit_name(path):
    """The config validates by asking the chosen unit, never by `if pde == "elasticity"`."""
    assert not compared_names(path)


@pytest.mark.parametrize("kind", INTERFACE)
def test_every_unit_has_its_interface(kind):
    for name, unit in units.KINDS[kind].items():
        assert unit.NAME == name
        missing = [attr for attr in INTERFACE[kind] if not hasattr(unit, attr)]
        assert not missing, f"{unit.__name__} lacks {missing}"
        if unit.SECTION is not None:
            assert callable(unit.section), unit.__name__
        if kind == "study_type" and unit.LIMIT is not None:
            assert callable(unit.parse_limit), unit.__name__


def digest(data):
    """sha256 of data as sorted JSON, the repository's own path left out (gmsh and .msh paths are stored resolved)."""
    text = json.dumps(data, sort_keys=True, default=str).replace(str(ROOT), "<repository>")
    return hashlib.sha256(text.encode()).hexdigest()


# digests of the resolved dict and the hashed settings of every shipped config (a map's points too), computed
# before the config was cut into modules; problem.method was added after them, at its default penalty, and the
# P2 configs were recomputed when their contact_quadrature default became the exact rule, hertz.yaml when it
# gained the Hertz measures and a fifth level
SHIPPED = json.loads((Path(__file__).parent / "shipped_configs.json").read_text())


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_shipped_config_resolves_and_hashes_as_before(name):
    if not (ROOT / name).exists():
        pytest.skip(f"{name} is no longer shipped")
    cfg = config.load(ROOT / name)
    resolved = config.to_dict(cfg)
    assert resolved["problem"].pop("method") == "penalty"
    points = [digest(config.canonical(point)) for point in cfg.map.studies] if cfg.map else []
    assert {"resolved": digest(resolved), "hashed": digest(config.canonical(cfg)), "points": points} == SHIPPED[name]


def test_method_penalty_is_the_default_and_hashes_as_before_the_key():
    """problem.method enters the hash only when it is not its default: results recorded before the key resume."""
    given, implied = load({"problem": {"method": "penalty"}}), load({})
    assert given.problem.method == implied.problem.method == "penalty"
    assert config.fingerprint(given) == config.fingerprint(implied)
    assert "method" not in config.canonical(implied)["problem"]
    assert config.to_dict(implied)["problem"]["method"] == "penalty"


@pytest.mark.parametrize("changes, message", [
    pytest.param({"problem": {"method": "nitsch"}}, "problem.method: 'nitsch' is not one of penalty", id="method"),
    pytest.param({"problem": {"pde": "stokes"}}, "problem.pde: 'stokes' is not one of poisson, elasticity",
                 id="pde"),
    pytest.param({"problem": {"gap": "0"}}, "problem.gap: only meaningful with problem.pde: elasticity", id="gap"),
    pytest.param({"material": {"E": 2}}, "material: only meaningful with problem.pde: elasticity", id="section"),
    pytest.param({"map": {"grid": {"alpha": [1, 2]}}}, "map: only meaningful with study_type map", id="map"),
    pytest.param({"limit": {"epsilon": [1, 0.1]}}, "limit: only meaningful with study_type epsilon_sweep or "
                                                   "total_error", id="limit"),
    pytest.param({"materal": {"E": 2}}, r"materal: unknown key in config \(did you mean 'material'\?\)",
                 id="registered-section-suggested"),
])
def test_unit_rules_refuse_with_the_key(changes, message):
    with pytest.raises(config.ConfigError, match="^" + message):
        load(changes)


def test_registered_section_in_template_and_reference():
    """A unit's section is documented where the core ones are: `signorini init`, the reference, did-you-mean."""
    assert "material.E" in config.key_paths() and "problem.method" in config.key_paths()
    assert "# material:" in config.template()


def test_check_loads_no_dolfinx():
    """The unit modules are light: validating every shipped kind of config imports neither dolfinx nor PETSc."""
    code = ("import sys; from signorini_cli import config; config.load('configs/elasticity/square-alpha2.yaml'); "
            "config.load('configs/limit/total.yaml'); print('dolfinx' in sys.modules, 'petsc4py' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]


@dataclasses.dataclass(frozen=True)
class Nitsche:
    """The section of a method registered for the test below."""
    theta: float = schema.key(1.0, "1 | 0 | -1")
    gamma0: float = schema.key(1.0, "> 0")


def nitsche_section(raw, path):
    check.keys(raw, path, optional=schema.keys_of(Nitsche))
    s = check.Section(raw, path, Nitsche)
    if s.number("theta") not in (1.0, 0.0, -1.0):
        raise config.ConfigError(s.at("theta"), f"must be 1, 0 or -1, got {s.get('theta')}")
    return Nitsche(s.number("theta"), s.number("gamma0", positive=True))


@pytest.fixture
def nitsche(monkeypatch):
    """A method with its own section registered as a module of config/ would be: a namespace and one line."""
    unit = types.SimpleNamespace(NAME="nitsche", DOC="", PDES=("poisson",), UNUSED={"epsilon": ""},
                                 SECTION=schema.UnitSection("nitsche", Nitsche, "{theta, gamma0}"),
                                 section=nitsche_section, check_config=lambda cfg, raw: cfg)
    monkeypatch.setitem(units.METHODS, "nitsche", unit)


def test_a_method_registers_its_own_section(nitsche):
    cfg = load({"epsilon": None, "problem": {"method": "nitsche"}, "nitsche": {"theta": -1}})
    assert (cfg.problem.method, cfg.nitsche) == ("nitsche", Nitsche(theta=-1.0))
    resolved = config.to_dict(cfg)
    assert resolved["nitsche"] == {"theta": -1.0, "gamma0": 1.0} and "epsilon" not in resolved
    assert config.fingerprint(config.from_dict(resolved)) == config.fingerprint(cfg)  # reads back
    assert config.fingerprint(cfg) != config.fingerprint(load({"epsilon": None, "problem": {"method": "nitsche"}}))
    assert "nitsche.gamma0" in config.key_paths() and "# nitsche:" in config.template()


@pytest.mark.parametrize("changes, message", [
    pytest.param({"nitsche": {"theta": 1}}, "nitsche: only meaningful with problem.method: nitsche", id="no-method"),
    pytest.param({"problem": {"method": "nitsche"}}, "epsilon: not used by problem.method nitsche", id="unused"),
    pytest.param({"epsilon": None, "problem": {"method": "nitsche", "pde": "elasticity",
                                               "exact": ["x", "y"]}},
                 r"problem.method: nitsche is not built for pde: elasticity \(it is for poisson\)", id="pde"),
    pytest.param({"epsilon": None, "problem": {"method": "nitsche"}, "nitsche": {"theta": 2}},
                 "nitsche.theta: must be 1, 0 or -1, got 2", id="section-checked"),
])
def test_a_registered_method_refuses_with_the_key(nitsche, changes, message):
    with pytest.raises(config.ConfigError, match="^" + message):
        load(changes)
