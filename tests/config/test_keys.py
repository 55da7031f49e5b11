"""No config key is silently ignored: every key of the reference, set to a value other than its default, either
changes the resolved config or is refused with its name, in every kind of study; and what the reference says is
required or defaulted is what the loader requires or defaults."""
import copy
import functools
from pathlib import Path

import pytest
import yaml

from signorini_cli import config
from signorini_cli.config import reading, rendering
from conftest import BASE, U_SIGNORINI, merge

ROOT = Path(__file__).resolve().parents[2]
ELASTIC = {"pde": "elasticity", "exact": ["0.1*sin(pi*x)*y", "0.1*cos(2*pi*x)*(1 - y)**2"]}
LIMIT_BASE = {"alpha": None, "epsilon": None, "problem": {"exact": U_SIGNORINI, "exact_solves": "signorini"}}
# one config of each kind a key can apply to (the "applies" column of the reference)
CONTEXTS = {
    "scalar": {"dimension": None},
    "data-only": {"problem": {"exact": None, "f": "-10"}},
    "elasticity": {"problem": ELASTIC},
    "power-law": {"epsilon": {"law": "power", "exponent": 1.5}},
    "smooth": {"positive_part": {"kind": "smooth"}},
    "newtontr": {"solver": {"method": "newtontr"}},
    "expect": {"expect": {"rates": {"L2": 2.0}}},
    "signorini": merge(LIMIT_BASE, {"study_type": "signorini"}),
    "epsilon_sweep": merge(LIMIT_BASE, {"study_type": "epsilon_sweep", "limit": {"epsilon": [1.0, 0.1]}}),
    "total_error": merge(LIMIT_BASE, {"study_type": "total_error", "limit": {"exponent": [1.0]}}),
    "map": {"study_type": "map", "map": {"grid": {"alpha": [1.5, 2.0]}}},
    "gmsh": {"mesh": {"kind": "gmsh", "geometry": "half_disk", "sizes": [0.4], "refinements": None},
             "contact": "contact"},
    "file": {"mesh": {"kind": "file", "path": str(ROOT / "meshes/examples/quarter_annulus.msh"),
                      "refine": "uniform", "refinements": [0, 1]}, "contact": "inner_arc"},
}
# a value other than the default (and than every context's) for each key
OTHER = {
    "study": "other", "description": "a study", "dimension": 3, "alpha": 1.5, "outside_theory": True,
    "epsilon.law": "theta_sqrt_h", "epsilon.theta": 0.5, "epsilon.exponent": 2.0,
    "mesh.kind": "unit_cube", "mesh.refinements": [2, 3], "mesh.diagonal": "crossed", "mesh.geometry": "l_shape",
    "mesh.sizes": [0.3], "mesh.path": str(ROOT / "meshes/examples/quarter_annulus.msh"), "mesh.refine": "uniform",
    "mesh.cache": "cache", "contact": "left", "problem.exact": "x*(1-y)", "problem.f": "-1", "problem.g": "0.5",
    "problem.exact_solves": "signorini", "problem.define": {"r": "x*y"}, "problem.pde": "elasticity",
    "problem.method": "nitsche", "problem.gap": "0.1", "problem.normal": [0.0, -2.0], "problem.hertz_radius": 2.0,
    "positive_part.kind": "smooth", "positive_part.delta": "1e-3*h", "contact_quadrature": "vertex",
    "element.degree": 2, "solver.rtol": 1e-9, "solver.atol": 1e-11, "solver.max_it": 20, "solver.linear": "direct",
    "solver.line_search": "basic", "solver.on_failure": "stop", "solver.petsc_options": {"ksp_type": "gmres"},
    "solver.strategy": "plain", "solver.method": "newtontr", "solver.stol": 0.0, "solver.preconditioner": "gamg",
    "solver.linear_rtol": 1e-8, "solver.linear_fallback": False, "solver.inexact": True,
    "solver.continuation.start": 0.5, "solver.continuation.factor": 0.5, "solver.continuation.max_steps": 5,
    "solver.condition_max_dofs": 100, "solver.linear_floor": True, "solver.polish": 0, "output.dir": "elsewhere",
    "output.plots": False, "output.fields": True, "output.digits": 5, "output.columns": "all",
    "output.figure_width": "390pt", "verification.fit_levels": 2, "verification.tolerance": 0.3,
    "verification.measures": ["L2_gc"], "verification.reference_refinements": 1,
    "verification.reference_epsilon": "fixed", "verification.regular": False, "expect.rates": {"H1": 1.0},
    "expect.tolerance": 0.2, "study_type": "signorini", "map.grid": {"epsilon.theta": [0.5, 2.0]},
    "map.points": [{"alpha": 1.2}], "map.jobs": 2, "map.ranks_per_point": 2,
    "limit.alpha": [1.5, 3.0], "limit.epsilon": [1.0, 0.5, 0.25], "limit.theta": 2.0, "limit.exponent": [2.0],
    "limit.fit_last": 2, "material.E": 2.0, "material.nu": 0.25,
}
LEAVES = [path for path, default, doc, only in rendering.documented_keys()
          if not any(other.startswith(path + ".") for other in config.key_paths())]


def raw_of(context):
    return copy.deepcopy(merge(BASE, CONTEXTS[context]))  # merge shares the values it adds


def load(raw):
    return config.loads(yaml.safe_dump(raw))


@functools.cache
def resolved_of(context):
    return config.to_dict(load(raw_of(context)))


def names(err, path):
    """Whether a refusal names the key: its path, a section holding it, a key under it or beside it in its
    section (mesh.geometry when mesh.kind becomes unit_cube), or its name in the message."""
    related = err.path == path or path.startswith(err.path + ".") or err.path.startswith(path + ".")
    beside = "." in path and err.path.rsplit(".", 1)[0] == path.rsplit(".", 1)[0]
    return related or beside or path.rsplit(".", 1)[-1] in err.message


def given(raw, path):
    """The raw value at a dotted path (None where it is not given)."""
    for part in path.split("."):
        raw = raw.get(part) if isinstance(raw, dict) else None
    return raw


@pytest.mark.fast
def test_every_key_has_another_value():
    assert sorted(set(LEAVES) - set(OTHER)) == []


@pytest.mark.parametrize("path", LEAVES)
def test_key_is_applied_or_refused_in_every_kind_of_study(path):
    """Set to another value, the key changes the resolved config, or it is refused naming it; and it is
    applied in at least one kind of study (about 0.1 s a key: not in the fast loop)."""
    applied = []
    for context in CONTEXTS:
        raw = raw_of(context)
        if given(raw, path) == OTHER[path]:
            continue  # the context has that value already
        reading.set_path(raw, path, copy.deepcopy(OTHER[path]))
        try:
            changed = config.to_dict(load(raw))
        except config.ConfigError as err:
            assert names(err, path), f"{context}: {err}"
            continue
        assert changed != resolved_of(context), f"{path} = {OTHER[path]!r} is ignored in the {context} config"
        applied.append(context)
    assert applied or path in NOT_APPLIED_ALONE, path


# keys that no context applies when set alone (each is refused there, naming it), with why
NOT_APPLIED_ALONE = {
    "problem.hertz_radius": "the physical elastic problem only (no exact): the elasticity context has one",
    "problem.method": "only penalty is registered: another method is refused",
    "dimension": "checked against the mesh, which sets it",
    # applied together with the keys they need, as in the contexts that give them: file, elasticity, signorini
    "mesh.path": "the one shipped .msh", "mesh.refine": "uniform needs refinements",
    "problem.pde": "elasticity needs exact per component", "study_type": "signorini needs u_S, no alpha and epsilon",
}


@pytest.mark.fast
@pytest.mark.parametrize("path, context", [
    pytest.param(path, context, id=f"{path}-{context}") for path, context in (
        ("study", "scalar"), ("mesh", "scalar"), ("mesh.kind", "scalar"), ("mesh.refinements", "scalar"),
        ("mesh.geometry", "gmsh"), ("mesh.sizes", "gmsh"), ("mesh.path", "file"), ("contact", "scalar"),
        ("problem", "scalar"), ("expect.rates", "expect"), ("map", "map"), ("limit", "epsilon_sweep"),
        ("limit.epsilon", "epsilon_sweep"), ("limit.exponent", "total_error"))])
def test_a_required_key_of_the_reference_is_required(path, context):
    """The reference says "required" with no default, and without the key the config is refused naming it."""
    row = next(row for row in rendering.documented_keys() if row[0] == path)
    assert row[1] == "" and row[2].startswith("required")
    raw = raw_of(context)
    *parents, name = path.split(".")
    parent = raw
    for part in parents:
        parent = parent[part]
    del parent[name]
    with pytest.raises(config.ConfigError, match=f"^{path.replace('.', '[.]')}: (missing|give)"):
        load(raw)


@pytest.mark.fast
def test_every_default_of_the_reference_is_the_loaders():
    """A key the reference gives a default (and that applies to every study) is optional, and left out it
    takes that default in the resolved config."""
    resolved = config.to_dict(load(raw_of("scalar")))
    for path, default, doc, only in rendering.documented_keys():
        section = path.rpartition(".")[0]
        if section and given(resolved, section) is None:
            continue  # an optional section not given (expect)
        if default and not only and given(raw_of("scalar"), path) is None and path != "dimension":  # the mesh's
            assert yaml.safe_load(default) == given(resolved, path), path


@pytest.mark.fast
def test_elasticity_applies_define():
    """problem.define holds for elasticity as for the scalar problem: its names in exact and gap."""
    cfg = load(merge(BASE, {"problem": {"pde": "elasticity", "define": {"s": "sin(pi*x)"},
                                        "exact": ["0.1*s*y", "0.1*(1 - y)**2"], "gap": "0.01*s"}}))
    assert [name for name, _ in cfg.problem.define] == ["s"]
    assert cfg.problem.exact[0]({"x": 0.5, "y": 1.0}, config.expressions.math_functions()) == pytest.approx(0.1)
    assert config.to_dict(cfg)["problem"]["define"] == {"s": "sin(pi*x)"}


@pytest.mark.fast
def test_elasticity_gap_refuses_eps_through_a_definition():
    with pytest.raises(config.ConfigError, match="^problem.gap: the initial gap cannot depend on eps"):
        load(merge(BASE, {"problem": dict(ELASTIC, define={"d": "eps*x"}, gap="d")}))


@pytest.mark.fast
@pytest.mark.parametrize("normal, unit", [
    pytest.param([1.0e200, 1.0e200], [2 ** -0.5, 2 ** -0.5], id="overflowing-square"),
    pytest.param([1.0e-200, 0.0], [1.0, 0.0], id="underflowing-square"),
    pytest.param([0.0, -3.0], [0.0, -1.0], id="plain"),
])
def test_elastic_normal_is_normalised_without_overflow(normal, unit):
    cfg = load(merge(BASE, {"problem": dict(ELASTIC, normal=normal)}))
    assert cfg.problem.normal == pytest.approx(unit, rel=1e-15)  # one rounding per entry
