"""Config validation: defaults, the epsilon laws, and rejections that name their key."""
import os
import re
import shutil
from pathlib import Path

import pytest
import yaml

from signorini_cli import config
from signorini_cli.config import geometry_files, schema
from conftest import BASE, merge

pytestmark = pytest.mark.fast


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
    assert cfg.positive_part.kind == "smooth" and cfg.positive_part.delta.text == "1e-2*h*sqrt(eps)"


@pytest.mark.parametrize("value", ["exact", "vertex", 6])
def test_contact_quadrature(value):
    assert load({}).contact_quadrature == "exact"  # the exact integrals by default
    cfg = load({"contact_quadrature": value})
    assert cfg.contact_quadrature == value and config.to_dict(cfg)["contact_quadrature"] == value


@pytest.mark.parametrize("changes, message", [
    ({"contact_quadrature": 0}, "must be >= 1, got 0"),
    ({"contact_quadrature": "gauss"}, "'gauss' is not one of exact, vertex"),
    ({"contact_quadrature": "vertex", "positive_part": "smooth"}, "vertex lumps the exact positive part"),
])
def test_contact_quadrature_rejected(changes, message):
    with pytest.raises(config.ConfigError, match=f"^contact_quadrature: {message}"):
        load(changes)


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
    pytest.param({"epsilon": {"thetta": 1}}, "epsilon.thetta: unknown key in epsilon \\(did you mean 'epsilon.theta'", id="typo-nested"),
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
    pytest.param({"problem": {"define": {"r": "sqrt(x**2 + y**2)", "t": "atan2(y, x)"},
                              "exact": "r**(2/3)*sin(2*t/3)"}}, id="define"),
    pytest.param({"outside_theory": True}, id="outside-theory"),
])
def test_to_dict_round_trip(changes):
    resolved = config.to_dict(load(changes))
    assert config.to_dict(config.from_dict(resolved)) == resolved
    assert list(resolved)[:2] == ["study", "description"] and "text" not in resolved


def test_define_feeds_exact_and_its_errors_name_the_key():
    cfg = load({"problem": {"define": {"r": "sqrt(x**2 + y**2)"}, "exact": "r**2"}})
    assert cfg.problem.exact({"x": 3.0, "y": 4.0}, config.expressions.math_functions()) == pytest.approx(25)
    with pytest.raises(config.ConfigError, match=r"^problem.define.r: unknown name 'q'"):
        load({"problem": {"define": {"r": "q*x"}, "exact": "r"}})
    with pytest.raises(config.ConfigError, match=r"^problem.define: must be a mapping"):
        load({"problem": {"define": ["r"], "exact": "x"}})


def test_outside_theory_lifts_condition_5():
    cube = {"dimension": 3, "mesh": {"kind": "unit_cube", "refinements": [2, 4]}, "alpha": 4.0}
    with pytest.raises(config.ConfigError, match=r"^alpha: must be <= 3 in 3-D .*outside_theory: true runs it"):
        load(cube)
    assert load(dict(cube, outside_theory=True)).alpha == 4.0


def test_verification_defaults_and_expect():
    cfg = load({"expect": {"rates": {"L2": 2, "H1": 1.0}}})
    assert cfg.verification == config.Verification(fit_levels=3, tolerance=0.2, measures=None,
                                                   reference_refinements=2, reference_epsilon="per_level")
    assert dict(cfg.expect.rates) == {"L2": 2.0, "H1": 1.0} and cfg.expect.tolerance == 0.1
    assert load({}).expect is None
    data = load({"problem": {"exact": None, "f": "10"}, "expect": {"rates": {"L2_ref": 2}},
                 "verification": {"reference_refinements": 2, "reference_epsilon": "fixed",
                                  "measures": ["diff", "energy"]}})
    assert data.verification.reference_epsilon == "fixed" and data.verification.measures == ("diff", "energy")


DATA_ONLY = {"problem": {"exact": None, "f": "10"}}


@pytest.mark.parametrize("changes, message", [
    pytest.param({"verification": {"fit_levels": 1}}, "verification.fit_levels: must be >= 2, got 1", id="fit"),
    pytest.param({"verification": {"tolerance": -0.1}}, "verification.tolerance: must be >= 0", id="tolerance"),
    pytest.param({"verification": {"measures": ["L2_gc", "area"]}},
                 r"verification.measures\[1\]: 'area' is not one of", id="measure"),
    pytest.param({"verification": {"measures": "L2_gc"}}, "verification.measures: must be a list",
                 id="measures-type"),
    pytest.param({"verification": {"measures": ["diff", "diff"]}}, "verification.measures: lists a measure twice",
                 id="measure-twice"),
    pytest.param({"verification": {"reference_epsilon": "fixed"}},
                 "verification.reference_epsilon: only meaningful without problem.exact", id="ref-eps-exact"),
    pytest.param(dict(DATA_ONLY, verification={"reference_refinements": 4}),
                 "verification.reference_refinements: must be <= 3, got 4", id="ref-refinements"),
    pytest.param(dict(DATA_ONLY, verification={"reference_epsilon": "each"}),
                 "verification.reference_epsilon: 'each' is not one of per_level, fixed", id="ref-eps"),
    pytest.param({"verification": {"fit_level": 3}}, "verification.fit_level: unknown key in verification "
                 r"\(did you mean 'verification.fit_levels'\?\)", id="typo"),
    pytest.param({"expect": {"rates": {"L3": 2}}}, "expect.rates.L3: not a rate column of a manufactured scene",
                 id="expect-norm"),
    pytest.param(dict(DATA_ONLY, expect={"rates": {"L2": 2}}),
                 r"expect.rates.L2: not a rate column of a data-only scene \(no exact solution\); one of L2_ref",
                 id="expect-exact-norm-data-only"),
    pytest.param({"expect": {"rates": {"L2": "two"}}}, "expect.rates.L2: must be a number", id="expect-rate"),
    pytest.param({"expect": {"rates": {}}}, "expect.rates: must be a mapping of norm to rate", id="expect-empty"),
    pytest.param({"expect": {"tolerance": 0.1}}, "expect.rates: missing required key", id="expect-no-rates"),
])
def test_verification_rejection_names_key(changes, message):
    with pytest.raises(config.ConfigError, match="^" + message):
        load(changes)


@pytest.mark.parametrize("changes", [
    pytest.param({"expect": {"rates": {"L2": 2.0}, "tolerance": 0.2}, "verification": {"fit_levels": 4}},
                 id="manufactured"),
    pytest.param(dict(DATA_ONLY, verification={"reference_epsilon": "fixed", "measures": ["diff"]},
                      expect={"rates": {"L2_ref": 2.0}}), id="data-only"),
])
def test_verification_keys_round_trip(changes):
    cfg = load(changes)
    again = config.from_dict(config.to_dict(cfg))
    assert (again.verification, again.expect) == (cfg.verification, cfg.expect)


SIGNORINI_PROBLEM = {"exact": "-x*y", "exact_solves": "signorini"}
SWEEP = {"study_type": "epsilon_sweep", "alpha": None, "epsilon": None, "problem": SIGNORINI_PROBLEM,
         "limit": {"alpha": [1, 2], "epsilon": {"start": 1.0, "stop": 1e-4, "count": 5}}}


def load_limit(changes):
    return config.loads(yaml.safe_dump(merge(merge(BASE, SWEEP), changes)))


def test_limit_sweep_geometric_range():
    cfg = load_limit({})
    assert cfg.study_type == "epsilon_sweep" and cfg.limit.alpha == (1.0, 2.0)
    assert cfg.limit.epsilon == pytest.approx((1.0, 1e-1, 1e-2, 1e-3, 1e-4))
    assert load({}).study_type == "refinement" and load({}).limit is None


def test_limit_total_error_defaults():
    cfg = load_limit({"study_type": "total_error", "limit": {"alpha": None, "epsilon": None, "exponent": [1, 2]}})
    assert cfg.limit.alpha == (2.0,) and cfg.limit.theta == 1.0 and cfg.limit.exponent == (1.0, 2.0)
    assert load({"problem": SIGNORINI_PROBLEM}).problem.exact_solves == "signorini"  # a refinement study too


@pytest.mark.parametrize("changes, message", [
    pytest.param({"study_type": "sweep"}, "study_type: 'sweep' is not one of refinement, signorini", id="type"),
    pytest.param({"study_type": None}, "limit: only meaningful with study_type", id="limit-refinement"),
    pytest.param({"alpha": 2}, r"alpha: not used by study_type epsilon_sweep \(give the α values as limit.alpha",
                 id="alpha-sweep"),
    pytest.param({"problem": {"exact_solves": None}}, "problem.exact_solves: study_type epsilon_sweep needs a "
                                                      "Signorini solution", id="compliance-exact"),
    pytest.param({"problem": {"exact": None, "exact_solves": None, "f": "1", "g": "1"}}, "problem.g: study_type "
                 "epsilon_sweep needs g = 0", id="g"),
    pytest.param({"problem": {"exact": "eps*x"}}, "problem.exact: a Signorini solution cannot depend on eps",
                 id="eps-in-u_S"),
    pytest.param({"limit": None}, "limit: missing: study_type epsilon_sweep needs a limit block", id="no-limit"),
    pytest.param({"limit": {"epsilon": [1e-2, 1e-1]}}, r"limit.epsilon: must be at least two decreasing",
                 id="increasing"),
    pytest.param({"limit": {"epsilon": {"start": 1e-3, "stop": 1.0, "count": 3}}},
                 "limit.epsilon: start must be larger than stop", id="range-up"),
    pytest.param({"limit": {"epsilon": {"count": None}}}, "limit.epsilon.count: missing", id="count"),
    pytest.param({"limit": {"alpha": [1, 0.5]}}, r"limit.alpha\[1\]: must be >= 1, got 0.5", id="alpha-low"),
    pytest.param({"limit": {"exponent": [1]}}, "limit.exponent: unknown key in limit", id="exponent-in-sweep"),
    pytest.param({"study_type": "total_error", "limit": {"epsilon": None, "exponent": [0]}},
                 r"limit.exponent\[0\]: must be > 0",
                 id="exponent"),
    pytest.param({"study_type": "total_error", "problem": {"exact": None, "exact_solves": None, "f": "1"},
                  "limit": {"epsilon": None, "exponent": [1]}}, "problem.exact: study_type total_error measures",
                 id="total-needs-exact"),
    pytest.param({"study_type": "signorini", "limit": None, "positive_part": "smooth"},
                 "positive_part: not used by study_type signorini", id="signorini-positive-part"),
])
def test_limit_rejection_names_key(changes, message):
    with pytest.raises(config.ConfigError, match="^" + message):
        load_limit(changes)


@pytest.mark.parametrize("name", ["signorini", "sweep", "total"])
def test_limit_to_dict_round_trip(name):
    resolved = config.to_dict(config.load(Path(__file__).resolve().parents[2] / "configs/limit" / f"{name}.yaml"))
    assert config.to_dict(config.from_dict(resolved)) == resolved  # `signorini check` prints a valid config


def test_limit_fields_only_for_refinement_levels():
    with pytest.raises(config.ConfigError, match="^output.fields: not written by study_type epsilon_sweep"):
        load_limit({"output": {"fields": True}})


def test_exponent_numbers_are_numbers():
    """YAML 1.1 (PyYAML) reads 1e-8 as a string; configs read it as the number YAML 1.2 says it is."""
    cfg = config.loads(yaml.safe_dump(BASE) + "solver: {rtol: 1e-8, atol: 1E-12}\n", ["epsilon.theta=5e-1"])
    assert cfg.solver.rtol == 1e-8 and cfg.solver.atol == 1e-12 and cfg.epsilon.theta == 0.5
    assert config.yaml_load("a: 8\nb: 1_0\nc: '1e3'") == {"a": 8, "b": 10, "c": "1e3"}


def test_duplicate_key_is_an_error():
    with pytest.raises(yaml.YAMLError, match="found duplicate key 'alpha'") as err:
        config.loads(yaml.safe_dump(BASE) + "alpha: 3.0\n")
    assert err.value.problem_mark.line + 1 == len(yaml.safe_dump(BASE).splitlines()) + 1


def test_yaml_merge_keys_are_not_duplicates():
    assert config.yaml_load("a: &x {k: 1}\nb:\n  <<: *x\n  j: 2\n") == {"a": {"k": 1}, "b": {"k": 1, "j": 2}}


def test_override_value_not_yaml():
    with pytest.raises(config.ConfigError, match=r"^--set mesh.refinements: '\[4' is not a YAML value"):
        config.loads(yaml.safe_dump(BASE), ["mesh.refinements=[4"])


HALF_DISK = {"kind": "gmsh", "geometry": "half_disk", "sizes": [0.2, 0.1]}
GEOMETRY_EXAMPLE = geometry_files.GEOMETRY_DIR / "examples" / "quarter_annulus.msh"


def load_mesh(mesh, **changes):
    """BASE with `mesh` in place of its unit square (replaced, not merged), Γ_C = the group `contact`."""
    raw = merge(BASE, dict({"contact": "contact", "dimension": None}, **changes))
    raw["mesh"] = mesh
    return config.loads(yaml.safe_dump(raw))


def test_gmsh_mesh_levels_and_dimension():
    cfg = load_mesh(HALF_DISK)
    assert cfg.dimension == 2 and cfg.mesh.levels == (0.2, 0.1) and cfg.mesh.level_key == "sizes"
    nested = load_mesh({"kind": "gmsh", "geometry": "half_ball", "sizes": [0.4], "refine": "uniform",
                        "refinements": [0, 2]}, problem={"exact": "x*z"})
    assert nested.dimension == 3 and nested.mesh.levels == (0, 2) and nested.mesh.level_key == "refinements"
    assert dict(nested.mesh.groups) == {"contact": 2, "dirichlet": 2, "domain": 3}


@pytest.mark.parametrize("mesh, changes, message", [
    pytest.param({"geometry": "disc"}, {}, "mesh.geometry: 'disc' is neither a shipped geometry", id="geometry"),
    pytest.param({"sizes": [0.1, 0.2]}, {}, r"mesh.sizes: must decrease", id="sizes-increasing"),
    pytest.param({"sizes": [0.1, -0.05]}, {}, r"mesh.sizes\[1\]: must be > 0", id="size-negative"),
    pytest.param({"refine": "uniform", "refinements": [0, 1]}, {},
                 "mesh.sizes: refine: uniform refines one base mesh, got 2", id="refine-two-sizes"),
    pytest.param({"sizes": [0.2], "refine": "uniform"}, {}, "mesh.refinements: must be a non-empty list",
                 id="refine-no-refinements"),
    pytest.param({"sizes": [0.2], "refine": "uniform", "refinements": [1, 1]}, {},
                 "mesh.refinements: must increase", id="refinements-repeat"),
    pytest.param({"refinements": [0, 1]}, {}, "mesh.refinements: only meaningful with refine: uniform",
                 id="refinements-without-refine"),
    pytest.param({"refine": "adaptive"}, {}, "mesh.refine: 'adaptive' is not one of none, uniform", id="refine"),
    pytest.param({"diagonal": "left"}, {}, "mesh.diagonal: unknown key in mesh", id="diagonal"),
    pytest.param({}, {"contact": "bottom"}, "contact: 'bottom' is not one of contact, dirichlet", id="group"),
    pytest.param({}, {"dimension": 3}, "mesh.kind: gmsh is 2-D but dimension is 3", id="dimension"),
])
def test_gmsh_mesh_rejection_names_key(mesh, changes, message):
    with pytest.raises(config.ConfigError, match="^" + message):
        load_mesh(dict(HALF_DISK, **mesh), **changes)


def test_file_mesh_missing_names_key():
    with pytest.raises(config.ConfigError, match="^mesh.path: no such mesh file: 'nowhere.msh'"):
        load_mesh({"kind": "file", "path": "nowhere.msh"})
    with pytest.raises(config.ConfigError, match=r"^mesh.path\[1\]: no such mesh file"):
        load_mesh({"kind": "file", "path": [str(GEOMETRY_EXAMPLE), "nowhere.msh"]})


@pytest.mark.parametrize("mesh", [
    pytest.param(HALF_DISK, id="gmsh-sizes"),
    pytest.param(dict(HALF_DISK, sizes=[0.2], refine="uniform", refinements=[0, 1]), id="gmsh-nested"),
    pytest.param({"kind": "file", "path": str(GEOMETRY_EXAMPLE)}, id="file"),
])
def test_gmsh_mesh_to_dict_round_trip(mesh):
    contact = "inner_arc" if mesh["kind"] == "file" else "contact"
    resolved = config.to_dict(load_mesh(mesh, contact=contact))
    assert config.to_dict(config.from_dict(resolved)) == resolved
    assert "groups" not in resolved["mesh"] and "diagonal" not in resolved["mesh"]


def test_gmsh_levels_compared_need_nested_family():
    with pytest.raises(config.ConfigError, match="^mesh.refine: levels meshed one by one are not nested"):
        load_mesh(HALF_DISK, problem={"exact": None, "f": "10"})
    nested = load_mesh(dict(HALF_DISK, sizes=[0.2], refine="uniform", refinements=[0, 1]),
                       problem={"exact": None, "f": "10"})
    assert nested.problem.exact is None
    with pytest.raises(config.ConfigError, match="^mesh.refine: levels meshed one by one"):
        load_mesh(HALF_DISK, verification={"measures": ["diff"]})


def test_gmsh_mesh_only_for_refinement_studies():
    with pytest.raises(config.ConfigError, match="^mesh.kind: gmsh meshes serve refinement studies, not study_type"):
        load_mesh(HALF_DISK, study_type="signorini", problem=SIGNORINI_PROBLEM)


def test_gmsh_geometry_change_changes_fingerprint(tmp_path):
    geo = tmp_path / "square.geo"
    geo.write_text(geometry_files.geometry_path("unit_square").read_text())
    before = config.fingerprint(load_mesh(dict(HALF_DISK, geometry=str(geo))))
    geo.write_text(geo.read_text().replace("Point(3) = {1, 1, 0};", "Point(3) = {1, 2, 0};"))
    assert config.fingerprint(load_mesh(dict(HALF_DISK, geometry=str(geo)))) != before  # resume refuses


def test_solver_strategy_defaults():
    solver = load({}).solver
    assert (solver.strategy, solver.method, solver.stol, solver.linear_fallback, solver.inexact) == \
        ("auto", "newtonls", 1e-7, True, False)
    assert solver.continuation == config.Continuation(start=1.0, factor=0.1, max_steps=20)
    assert solver.condition_max_dofs == 0


@pytest.mark.parametrize("changes, message", [
    pytest.param({"strategy": "smart"}, "solver.strategy: 'smart' is not one of plain, nested, continuation, auto",
                 id="strategy"),
    pytest.param({"method": "newtontr", "line_search": "bt"}, "solver.line_search: only meaningful with method: newtonls",
                 id="tr-line-search"),
    pytest.param({"preconditioner": "ilu"}, "solver.preconditioner: 'ilu' is not one of boomeramg, gamg", id="pc"),
    pytest.param({"inexact": "yes"}, "solver.inexact: must be true or false, got str 'yes'", id="inexact"),
    pytest.param({"continuation": {"factor": 2}}, "solver.continuation.factor: must be < 1", id="factor"),
    pytest.param({"continuation": {"steps": 3}}, "solver.continuation.steps: unknown key in solver.continuation "
                 "\\(did you mean 'solver.continuation.max_steps'", id="continuation-typo"),
    pytest.param({"condition_max_dofs": -1}, "solver.condition_max_dofs: must be >= 0", id="condition"),
    pytest.param({"stol": -1}, "solver.stol: must be >= 0", id="stol"),
])
def test_solver_strategy_rejection_names_key(changes, message):
    with pytest.raises(config.ConfigError, match="^" + message):
        load({"solver": changes})


# --- one place per fact: defaults, the ε law, the template ----------------------------------------

MINIMAL = {"study": "t", "mesh": {"kind": "unit_square", "refinements": [4]}, "contact": "bottom",
           "problem": {"exact": "x"}}


def test_defaults_are_the_dataclass_fields():
    """A config of the required keys only gets each section's dataclass default: the loader has none of its own."""
    cfg = config.loads(yaml.safe_dump(MINIMAL))
    assert (cfg.epsilon, cfg.positive_part, cfg.solver, cfg.output, cfg.verification) == \
        (config.Epsilon(), config.PositivePart(), config.Solver(), config.Output(), config.Verification())
    # the documented defaults
    assert (cfg.alpha, cfg.dimension, cfg.contact_quadrature, cfg.study_type) == (2.0, 2, "exact", "refinement")
    assert (cfg.solver.rtol, cfg.solver.max_it, cfg.epsilon.law, cfg.output.columns) == (1e-10, 50, "theta_h", "paper")


def test_loader_writes_no_default():
    """No `raw.get(key, <literal>)` in the config's modules: a default is written once, in its dataclass field."""
    for path in Path(schema.__file__).parent.glob("*.py"):
        assert not re.findall(r'\.get\("\w+", ["\d\[(\-]', path.read_text()), path.name


@pytest.mark.parametrize("epsilon, p, text, tex", [
    pytest.param({"law": "theta_h"}, 1.0, "h", r"\theta h", id="theta_h"),
    pytest.param({"law": "theta_sqrt_h", "theta": 2}, 0.5, "2√h", r"\theta\sqrt{h}", id="theta_sqrt_h"),
    pytest.param({"law": "constant", "theta": 0.1}, 0.0, "0.1", r"\theta", id="constant"),
    pytest.param({"law": "power", "exponent": 1.5}, 1.5, "h^1.5", r"\theta h^{1.5}", id="power"),
])
def test_epsilon_law_exponent_and_labels(epsilon, p, text, tex):
    eps = load({"epsilon": epsilon}).epsilon
    assert (eps.p, eps.formula(), eps.tex()) == (p, text, tex)


def test_epsilon_law_names_in_one_module():
    """A new ε law touches config/schema.py only: no other module of the package names a law."""
    for path in Path(schema.__file__).parents[1].rglob("*.py"):
        if path != Path(schema.__file__):
            text = path.read_text()
            assert not [law for law in config.LAWS if f'"{law}"' in text or f"'{law}'" in text], path.name


def test_template_is_a_config_of_the_defaults():
    cfg = config.loads(config.template())
    assert (cfg.epsilon, cfg.positive_part, cfg.solver, cfg.output, cfg.verification, cfg.mesh.diagonal) == \
        (config.Epsilon(), config.PositivePart(), config.Solver(), config.Output(), config.Verification(), "right")
    assert cfg.expect is None and cfg.limit is None


def test_template_lists_every_key_at_its_depth():
    text = config.template()
    for path in config.key_paths():
        name, depth = path.rsplit(".", 1)[-1], path.count(".")
        assert re.search(rf"^(# )?{'  ' * depth}{name}:", text, re.M), path
    assert "# limit:" in text and "#   epsilon:" in text  # optional blocks commented out as a whole


@pytest.mark.parametrize("changes, message", [
    pytest.param({"exact": "x*y"}, r"exact: unknown key in config \(did you mean 'problem.exact'\?\)$", id="exact"),
    pytest.param({"max_it": 3}, r"max_it: unknown key in config \(did you mean 'solver.max_it'\?\)$", id="max_it"),
    pytest.param({"solver": {"theta": 1}}, r"solver.theta: unknown key in solver \(did you mean 'epsilon.theta'",
                 id="theta-in-solver"),
    pytest.param({"output": {"plot": False}}, r"output.plot: unknown key in output \(did you mean 'output.plots'",
                 id="typo"),
    pytest.param({"colour": 1}, "colour: unknown key in config$", id="nothing-close"),
])
def test_did_you_mean_names_the_full_path(changes, message):
    with pytest.raises(config.ConfigError, match="^" + message):
        load(changes)


# --- input edges --------------------------------------------------------------------------------

@pytest.mark.parametrize("delta", ["-1", "0", "0*h", "1e300", "1e-200", "h - 0.01", "log(h)", "sqrt(eps - 1e-3)"])
def test_delta_must_be_positive_with_a_finite_square(delta):
    """δ = 0 or δ² = 0 (1e-200) makes the smoothed [u]_+ a kink (NaN Newton steps), δ² = inf (1e300)
    overflows; h - 0.01 and log(h) fail somewhere in h ∈ (0, 1]."""
    with pytest.raises(config.ConfigError, match=r"^positive_part.delta: must be > 0 with a finite"):
        load({"positive_part": {"kind": "smooth", "delta": delta}})


@pytest.mark.parametrize("delta", ["1e-2*h*sqrt(eps)", "h", "0.001", "eps"])
def test_delta_accepted(delta):
    assert load({"positive_part": {"kind": "smooth", "delta": delta}}).positive_part.delta.text == delta


def test_diagonal_only_for_unit_square():
    with pytest.raises(config.ConfigError, match="^mesh.diagonal: only meaningful with kind: unit_square"):
        load({"dimension": 3, "mesh": {"kind": "unit_cube", "diagonal": "left"}, "problem": {"exact": "x*z"}})
    cube = load({"dimension": 3, "mesh": {"kind": "unit_cube"}, "problem": {"exact": "x*z"}})
    assert "diagonal" not in config.to_dict(cube)["mesh"]  # `check` prints a config that loads again


def test_petsc_options_values_as_petsc_reads_them():
    options = {"snes_lag_preconditioner": -2, "ksp_view": None, "-ksp_monitor": "ascii:out.txt",
               "snes_ksp_ew": True, "ksp_rtol": 1e-8, "pc_type": "gamg"}
    assert dict(load({"solver": {"petsc_options": options}}).solver.petsc_options) == {
        "snes_lag_preconditioner": "-2", "ksp_view": "", "ksp_monitor": "ascii:out.txt", "snes_ksp_ew": "true",
        "ksp_rtol": "1e-08", "pc_type": "gamg"}


@pytest.mark.parametrize("options, message", [
    pytest.param({"snes_linesearch": {"type": "bt"}}, "snes_linesearch: must be a single value, not a mapping",
                 id="nested"),
    pytest.param({"snes_max_it": "abc"}, "snes_max_it: must be an integer, got 'abc'", id="max-it-abc"),
    pytest.param({"snes_max_it": 2.5}, "snes_max_it: must be an integer, got '2.5'", id="max-it-float"),
    pytest.param({"ksp_rtol": "nan"}, "ksp_rtol: must be a finite number", id="rtol-nan"),
    pytest.param({"snes_type": "ksponly"}, r"snes_type: the study chooses the SNES type .* set solver.method",
                 id="ksponly"),
    pytest.param({"snes_type": "newtontr"}, r"snes_type: the study chooses the SNES type", id="newtontr"),
    pytest.param({"snes_convergence_test": "skip"}, "snes_convergence_test: would replace the study's success "
                 "test; set solver.rtol, solver.atol and solver.stol instead", id="convergence-test"),
    pytest.param({"snes_atol": 1}, "snes_atol: would replace the study's success test; set solver.atol",
                 id="atol"),
    pytest.param({"snes_monitor": "loud"}, "snes_monitor: takes no value or a viewer", id="viewer"),
    pytest.param({"snes monitor": ""}, "snes monitor: is not a PETSc option name", id="name"),
])
def test_petsc_options_rejected_naming_the_option(options, message):
    with pytest.raises(config.ConfigError, match="^solver.petsc_options." + message):
        load({"solver": {"petsc_options": options}})


def test_petsc_options_from_the_command_line_join_the_config():
    cfg = config.loads(yaml.safe_dump(merge(BASE, {"solver": {"petsc_options": {"ksp_view": None}}})),
                       options=[("snes_monitor", ""), ("ksp_rtol", "1e-8")])
    assert cfg.solver.petsc_options == (("ksp_view", ""), ("snes_monitor", ""), ("ksp_rtol", "1e-8"))
    assert config.to_dict(cfg)["solver"]["petsc_options"] == {"ksp_view": "", "snes_monitor": "", "ksp_rtol": "1e-8"}
    with pytest.raises(config.ConfigError, match="^solver.petsc_options.snes_max_it: must be an integer"):
        config.loads(yaml.safe_dump(BASE), options=[("snes_max_it", "abc")])


@pytest.mark.parametrize("value, ok", [("exact", True), ("vertex", True), (3, True), (0, False),
                                       ("gauss", False), (True, False), (2.5, False)])
def test_contact_quadrature_values(value, ok):
    if ok:
        assert load({"contact_quadrature": value}).contact_quadrature == value
    else:
        with pytest.raises(config.ConfigError, match="^contact_quadrature: "):
            load({"contact_quadrature": value})


@pytest.mark.parametrize("value, ok", [("all", True), ("paper", True), (["N", "L2"], True), ([], False),
                                       ("some", False), ([1], False)])
def test_output_columns_values(value, ok):
    if ok:
        assert load({"output": {"columns": value}}).output.columns == (tuple(value) if isinstance(value, list)
                                                                       else value)
    else:
        with pytest.raises(config.ConfigError, match="^output.columns: "):
            load({"output": {"columns": value}})


def test_mesh_paths_relative_to_the_config_file(tmp_path, monkeypatch):
    folder = tmp_path / "study"
    folder.mkdir()
    shutil.copy(GEOMETRY_EXAMPLE, folder / "m.msh")
    shutil.copy(geometry_files.geometry_path("unit_square"), folder / "sq.geo")
    raw = merge(BASE, {"contact": "inner_arc", "dimension": None})
    raw["mesh"] = {"kind": "file", "path": "m.msh"}
    (folder / "file.yaml").write_text(yaml.safe_dump(raw))
    raw = merge(BASE, {"contact": "contact", "dimension": None})
    raw["mesh"] = {"kind": "gmsh", "geometry": "sq.geo", "sizes": [0.5], "cache": "cache"}
    (folder / "gmsh.yaml").write_text(yaml.safe_dump(raw))
    monkeypatch.chdir(tmp_path)  # another folder than the config's
    assert config.load("study/file.yaml").mesh.path == (str(folder / "m.msh"),)
    gmsh = config.load("study/gmsh.yaml").mesh
    assert (gmsh.geometry, gmsh.cache) == (str(folder / "sq.geo"), str(folder / "cache"))
    (folder / "m.msh").unlink()
    with pytest.raises(config.ConfigError, match=r"^mesh.path: no such mesh file: 'm.msh' \(relative to the "):
        config.load("study/file.yaml")


@pytest.mark.parametrize("kind", ["fifo", "device", "folder", "too-big"])
def test_config_read_only_from_a_small_regular_file(kind, tmp_path):
    """A FIFO or /dev/zero would block or never end, 50 MB of YAML takes a minute to parse: refused at once."""
    path = {"fifo": tmp_path / "fifo", "device": Path("/dev/zero"), "folder": tmp_path,
            "too-big": tmp_path / "big.yaml"}[kind]
    if kind == "fifo":
        os.mkfifo(path)
    if kind == "too-big":
        with open(path, "wb") as file:
            file.truncate(config.MAX_BYTES + 1)
    message = "more than a config's limit" if kind == "too-big" else "not a regular file"
    with pytest.raises(config.ConfigError, match=message):
        config.load(path)


def billion_laughs(levels=9):
    """YAML of a few hundred bytes whose aliases expand to 10^levels values."""
    lines = ["l0: &l0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"l{k}: &l{k} [" + ", ".join([f"*l{k - 1}"] * 10) + "]" for k in range(1, levels)]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("where", ["top", "petsc_options"])
def test_alias_bomb_rejected_before_it_expands(where):
    text = billion_laughs() if where == "top" else yaml.safe_dump(BASE) + "solver:\n  petsc_options:\n" + \
        "".join("    " + line + "\n" for line in billion_laughs().splitlines())
    with pytest.raises(config.ConfigError, match="^YAML expands to more than 100000 values"):
        config.loads(text)


def test_recursive_alias_rejected():
    with pytest.raises(config.ConfigError, match="^YAML alias refers to itself"):
        config.yaml_load("a: &a [*a]\n")


def test_aliases_below_the_limit_load():
    assert config.yaml_load(billion_laughs(levels=4))["l3"][0][0][0] == ["x"] * 10


def test_delta_check_survives_an_overflowing_law():
    """eps = h^-100 overflows a float at h = 1e-6: the δ check skips that point instead of crashing."""
    cfg = load({"epsilon": {"law": "power", "exponent": -100}, "positive_part": "smooth"})
    assert cfg.positive_part.delta.text == config.DEFAULT_DELTA


def test_set_replaces_a_map_grid_key_written_dotted():
    # the guide's example: --set map.grid.epsilon.theta=[1,10] on a grid that writes `epsilon.theta: [...]`
    text = yaml.safe_dump(merge(BASE, {"study_type": "map",
                                       "map": {"grid": {"epsilon.theta": [0.5, 1.0], "alpha": [1.5, 2.0]}}}))
    cfg = config.loads(text, overrides=["map.grid.epsilon.theta=[1,10]"])
    assert sorted({point.epsilon.theta for point in cfg.map.studies}) == [1.0, 10.0]
