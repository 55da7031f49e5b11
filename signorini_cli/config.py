"""Study configuration: YAML -> validated, frozen dataclasses. Every error names its key path."""
import dataclasses
import difflib
import hashlib
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from . import expressions, geometry_files

LAWS = ("theta_h", "theta_sqrt_h", "constant", "power")
MESH_KINDS = {"unit_square": 2, "unit_cube": 3}
GEOMETRY_KINDS = ("gmsh", "file")  # meshes from a .geo geometry or from .msh files (physical groups)
REFINE = ("none", "uniform")
FACES = {2: ("left", "right", "bottom", "top"),
         3: ("left", "right", "front", "back", "bottom", "top")}
DIAGONALS = ("right", "left", "crossed")
POSITIVE_PARTS = ("exact", "smooth")
CONTACT_QUADRATURES = ("exact", "vertex")  # or an integer >= 1: a Gauss rule of that degree (issue 17)
# smoothing of [u]_+: delta^2/eps is the flux error off contact, so delta ~ h sqrt(eps) keeps it O(h^2)
# for every eps; docs/stability.md (make stiff) measures the laws this was chosen from
DEFAULT_DELTA = "1e-2*h*sqrt(eps)"
LINEAR_SOLVERS = ("auto", "direct", "iterative")  # auto: direct in 2-D, iterative in 3-D
LINE_SEARCHES = ("bt", "basic", "l2", "cp")
ON_FAILURE = ("continue", "stop")
STRATEGIES = ("plain", "nested", "continuation", "auto")
METHODS = ("newtonls", "newtontr")  # PETSc SNES types: line-search Newton, trust-region Newton
PRECONDITIONERS = ("boomeramg", "gamg")  # algebraic multigrid for linear: iterative
MAX_ALPHA_3D = 3.0  # the paper's condition (5): 1 <= alpha <= 3 when d = 3
COORDINATES = {2: ("x", "y"), 3: ("x", "y", "z")}
# verification.measures: what a level measures beyond L2/H1 (issue 4; README "Verification")
MEASURES = ("L2_gc", "pos_gc", "energy_err", "penetration", "contact_measure", "contact_force", "energy", "diff")
REFERENCE_EPSILONS = ("per_level", "fixed")
MAX_REFERENCE_REFINEMENTS = 2
# rate columns an `expect:` block may name: exact-solution errors, errors against a reference, differences
ERROR_NORMS = ("L2", "H1", "L2_gc", "pos_gc", "pos_gc_scaled", "energy_err")
REFERENCE_NORMS = tuple(f"{norm}_ref" for norm in ERROR_NORMS) + ("diff_L2", "diff_H1")
STUDY_TYPES = ("refinement", "signorini", "epsilon_sweep", "total_error")  # the last three: docs/limit.md
EXACT_SOLVES = ("compliance", "signorini")


class ConfigError(ValueError):
    """A bad config value; str() starts with the key path."""

    def __init__(self, path, message):
        self.path, self.message = path, message
        super().__init__(f"{path}: {message}" if path else message)


@dataclass(frozen=True)
class Epsilon:
    """The penalty law eps(h) (SPEC: theta_h, theta_sqrt_h, constant, power)."""
    law: str = "theta_h"
    theta: float = 1.0
    exponent: float = 1.0  # only for law: power

    def __call__(self, h):
        power = {"theta_h": 1.0, "theta_sqrt_h": 0.5, "constant": 0.0, "power": self.exponent}
        return self.theta * h ** power[self.law]


@dataclass(frozen=True)
class Mesh:
    kind: str = "unit_square"
    refinements: tuple = (8, 16, 32, 64)
    diagonal: str = "right"
    geometry: str = ""          # gmsh: a shipped name (meshes/<name>.geo) or a .geo file
    sizes: tuple = ()           # gmsh: target cell size per level (the base mesh's with refine: uniform)
    path: tuple = ()            # file: .msh files, one per level (the base mesh with refine: uniform)
    refine: str = "none"        # gmsh/file: uniform = levels are refinements of one base mesh (nested)
    cache: str = geometry_files.CACHE_DIR
    groups: tuple = ()          # gmsh/file: (name, dimension) of the source's named physical groups
    source_hash: str = ""       # gmsh/file: of the .geo/.msh contents, so a changed file changes the config hash

    @property
    def level_key(self):
        """The config key listing one entry per level."""
        if self.kind in MESH_KINDS or self.refine == "uniform":
            return "refinements"
        return "sizes" if self.kind == "gmsh" else "path"

    @property
    def levels(self):
        """One entry per level: cells per side, refinements of the base, gmsh sizes or .msh paths."""
        return getattr(self, self.level_key)

    @property
    def dimension(self):
        return MESH_KINDS.get(self.kind) or max(dim for _, dim in self.groups)


@dataclass(frozen=True)
class Problem:
    """A manufactured solution `exact`, or data `f` (and `g`) only."""
    exact: expressions.Expression = None
    f: expressions.Expression = None
    g: expressions.Expression = None
    exact_solves: str = "compliance"  # signorini: `exact` is a Signorini solution u_S, g = 0 (docs/limit.md)


@dataclass(frozen=True)
class PositivePart:
    """[u]_+ exactly, or smoothed as (u + sqrt(u^2 + delta^2))/2 with delta an expression in h, eps."""
    kind: str = "exact"
    delta: expressions.Expression = None


@dataclass(frozen=True)
class Continuation:
    """eps-continuation: from max(start, eps) down to eps, first step eps_{k+1} = factor * eps_k."""
    start: float = 1.0
    factor: float = 0.1
    max_steps: int = 20


@dataclass(frozen=True)
class Solver:
    rtol: float = 1e-10  # success: ||F|| <= rtol * (norm of the load without the penalty term)
    atol: float = 1e-12
    max_it: int = 50
    linear: str = "auto"
    line_search: str = "bt"
    on_failure: str = "continue"
    petsc_options: tuple = ()  # (name, value) pairs passed to PETSc under the study's prefix
    strategy: str = "auto"
    method: str = "newtonls"
    stol: float = 1e-7  # success: Newton correction <= stol * ||u_h|| (README, "Robust solves")
    preconditioner: str = "boomeramg"
    linear_rtol: float = 1e-10
    linear_fallback: bool = True
    inexact: bool = False  # Eisenstat-Walker forcing of the iterative linear tolerance
    continuation: Continuation = Continuation()
    condition_max_dofs: int = 0  # estimate cond(J) on levels with at most this many dofs
    linear_floor: bool = False  # time one linear solve of the converged Jacobian per level (make bench)


@dataclass(frozen=True)
class Verification:
    """Rate fits, verdict tolerance, extra measures, and the reference solution of data-only scenes."""
    fit_levels: int = 3          # least-squares slope over the last k converged levels
    tolerance: float = 0.1       # verdict: agrees when observed >= proven - tolerance
    measures: tuple = None       # None: every measure the scene can have
    reference_refinements: int = 1   # data-only scenes: uniform refinements of the finest level (0: none)
    reference_epsilon: str = "per_level"  # per_level: reference at each level's eps | fixed: one eps
    regular: bool = True  # false: u is not in W^{2,alpha+1} (corners, Γ_C meeting Γ_D): verdicts "not covered"


@dataclass(frozen=True)
class Expect:
    """Rates the user requires: exit status 1 when an observed fitted rate < rate - tolerance."""
    rates: tuple = ()            # (norm, rate) pairs
    tolerance: float = 0.1


@dataclass(frozen=True)
class Limit:
    """The ε → 0 studies (docs/limit.md): the α values, the ε of a sweep, the ε = θ h^p of a total-error study."""
    alpha: tuple = (2.0,)
    epsilon: tuple = ()    # epsilon_sweep: decreasing ε values
    theta: float = 1.0     # total_error: ε = θ h^p
    exponent: tuple = ()   # total_error: the p values
    fit_last: int = 3      # the fitted rate uses this many finest points


@dataclass(frozen=True)
class Output:
    dir: str = "results"
    plots: bool = True    # PNG/PDF convergence, work-precision and Newton plots at the end of `run`
    fields: bool = False  # u_h, its error and the Γ_C contact indicator per level as XDMF (ParaView)
    digits: int = 3       # digits after the point of errors, h and eps in rates.md / rates.tex


@dataclass(frozen=True)
class Config:
    study: str
    dimension: int
    alpha: float
    epsilon: Epsilon
    mesh: Mesh
    contact: str
    problem: Problem
    positive_part: PositivePart = PositivePart()
    contact_quadrature: object = "exact"  # CONTACT_QUADRATURES or an integer degree
    solver: Solver = Solver()
    output: Output = Output()
    description: str = ""
    verification: Verification = Verification()
    expect: Expect = None
    study_type: str = "refinement"
    limit: Limit = None
    text: str = field(default="", repr=False, compare=False)  # the YAML as given, for the record

    @property
    def output_dir(self):
        return Path(self.output.dir) / self.study


# --- loading -----------------------------------------------------------------------------------

def load(path, overrides=()):
    """Read a YAML config file, apply `KEY=VALUE` overrides, validate."""
    data = Path(path).read_bytes()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        line = data.count(b"\n", 0, err.start) + 1
        raise ConfigError("", f"not a UTF-8 text file (byte 0x{data[err.start]:02x} on line {line})") from None
    return loads(text, overrides)


def loads(text, overrides=()):
    """Validate YAML text (after overrides) into a Config."""
    raw = yaml_load(text)
    if not isinstance(raw, dict):
        raise ConfigError("", "the config must be a YAML mapping of keys to values")
    for item in overrides:
        apply_override(raw, item)
    return dataclasses.replace(from_dict(raw), text=text)


def apply_override(raw, item):
    """Set `a.b.c=value` in the raw mapping; the value is parsed as YAML, then validated as usual."""
    key, sep, value = item.partition("=")
    if not sep or not key.strip():
        raise ConfigError("--set", f"expected KEY=VALUE, got {item!r}")
    parts = key.strip().split(".")
    node = raw
    for i, part in enumerate(parts[:-1]):
        child = node.get(part)
        if child is None or not isinstance(child, dict):
            if child is not None and not isinstance(child, dict):
                raise ConfigError(".".join(parts[:i + 1]), "is not a mapping, cannot set a sub-key")
            child = node[part] = {}
        node = child
    try:
        node[parts[-1]] = yaml_load(value)
    except yaml.YAMLError as err:
        problem = getattr(err, "problem", None) or err
        raise ConfigError(f"--set {key.strip()}", f"{value!r} is not a YAML value: {problem}") from None


def from_dict(raw):
    """Validate a raw mapping into a Config."""
    _keys(raw, "", required=("study", "mesh", "contact"),
          optional=("dimension", "alpha", "epsilon", "problem", "positive_part", "contact_quadrature", "solver",
                    "output", "description", "verification", "expect",
                    "study_type", "limit"))
    study = _string(raw["study"], "study")
    if "/" in study or study in (".", ".."):
        raise ConfigError("study", f"must be a plain folder name, got {study!r}")
    mesh = _mesh(raw["mesh"], "mesh")
    dim = _integer(raw.get("dimension", mesh.dimension), "dimension")
    if dim not in (2, 3):
        raise ConfigError("dimension", f"must be 2 or 3, got {dim}")
    if mesh.dimension != dim:
        raise ConfigError("mesh.kind", f"{mesh.kind} is {mesh.dimension}-D but dimension is {dim}")
    alpha = _number(raw.get("alpha", 2.0), "alpha", low=1.0)
    if dim == 3 and alpha > MAX_ALPHA_3D:
        raise ConfigError("alpha", f"must be <= 3 in 3-D (the paper's condition (5)), got {alpha:g}")
    positive = _positive_part(raw.get("positive_part", "exact"), "positive_part")
    base = Config(study=study, dimension=dim, alpha=alpha,
                  epsilon=_epsilon(raw.get("epsilon", {}), "epsilon"),
                  mesh=mesh, contact=_contact(raw["contact"], mesh, dim),
                  problem=_problem(raw.get("problem"), "problem", dim),
                  positive_part=positive,
                  contact_quadrature=_contact_quadrature(raw.get("contact_quadrature", "exact"), positive.kind),
                  solver=_solver(raw.get("solver", {}), "solver"),
                  output=_output(raw.get("output", {}), "output"),
                  verification=_verification(raw.get("verification", {}), "verification", raw.get("problem")),
                  expect=_expect(raw["expect"], "expect", raw.get("problem")) if "expect" in raw else None,
                  description=_string(raw.get("description", ""), "description", empty=True))
    return _study_type(_check_geometry_mesh(base, raw), raw)


def _check_geometry_mesh(cfg, raw):
    """gmsh/file meshes serve refinement studies; levels that gmsh meshes one by one are not nested (on a
    curved boundary not even the same polygon), but a reference solution or successive differences move
    each level onto a finer one."""
    v, mesh = cfg.verification, cfg.mesh
    if mesh.kind in GEOMETRY_KINDS and raw.get("study_type", "refinement") != "refinement":
        raise ConfigError("mesh.kind", f"{mesh.kind} meshes serve refinement studies, not study_type "
                                       f"{raw['study_type']}")
    data_only = cfg.problem.exact is None
    diff = "diff" in (v.measures if v.measures is not None else ("diff",) if data_only else ())
    compared = diff or (data_only and v.reference_refinements > 0)
    if compared and mesh.kind in GEOMETRY_KINDS and mesh.refine == "none" and len(mesh.levels) > 1:
        raise ConfigError("mesh.refine", "levels meshed one by one are not nested, but a reference solution "
                                         "or successive differences compare levels on finer meshes: use "
                                         "refine: uniform (or verification.measures without diff and "
                                         "reference_refinements: 0)")
    return cfg


def _epsilon(raw, path):
    _keys(raw, path, optional=("law", "theta", "exponent"))
    law = _choice(raw.get("law", "theta_h"), f"{path}.law", LAWS)
    if "exponent" in raw and law != "power":
        raise ConfigError(f"{path}.exponent", f"only meaningful with law: power, not {law}")
    exponent = _number(raw.get("exponent", 1.0), f"{path}.exponent")
    return Epsilon(law, _number(raw.get("theta", 1.0), f"{path}.theta", positive=True), exponent)


def _mesh(raw, path):
    if isinstance(raw, dict) and raw.get("kind") in GEOMETRY_KINDS:
        return _geometry_mesh(raw, path)
    _keys(raw, path, required=("kind", "refinements"), optional=("diagonal",))
    kind = _choice(raw["kind"], f"{path}.kind", tuple(MESH_KINDS) + GEOMETRY_KINDS)
    levels = raw["refinements"]
    if not isinstance(levels, list) or not levels:
        raise ConfigError(f"{path}.refinements", f"must be a non-empty list of cells per side, got {levels!r}")
    levels = tuple(_integer(n, f"{path}.refinements[{i}]", low=1) for i, n in enumerate(levels))
    for i in range(1, len(levels)):
        if levels[i] <= levels[i - 1]:
            raise ConfigError(f"{path}.refinements", f"must increase, got {list(levels)}")
    diagonal = _choice(raw.get("diagonal", "right"), f"{path}.diagonal", DIAGONALS)
    return Mesh(kind, levels, diagonal)


def _geometry_mesh(raw, path):
    """mesh: {kind: gmsh, geometry, sizes} or {kind: file, path}, optionally refine: uniform + refinements."""
    kind = raw["kind"]
    source, listed = ("geometry", "sizes") if kind == "gmsh" else ("path", "path")
    _keys(raw, path, required=("kind", source, listed),
          optional=("refine", "refinements", "cache"))
    refine = _choice(raw.get("refine", "none"), f"{path}.refine", REFINE)
    if kind == "gmsh":
        geometry = _string(raw["geometry"], f"{path}.geometry")
        sources = (_geometry_file(geometry, f"{path}.geometry"),)
        entries = _sizes(raw["sizes"], f"{path}.sizes")
    else:
        entries = _msh_files(raw["path"], f"{path}.path")
        sources, geometry = entries, ""
    if refine == "uniform":
        if len(entries) != 1:
            raise ConfigError(f"{path}.{listed}", f"refine: uniform refines one base mesh, got {len(entries)}")
        refinements = _refinements(raw.get("refinements"), f"{path}.refinements")
    elif "refinements" in raw:
        raise ConfigError(f"{path}.refinements", "only meaningful with refine: uniform")
    else:
        refinements = ()
    return Mesh(kind, refinements, geometry=geometry, sizes=entries if kind == "gmsh" else (),
                path=entries if kind == "file" else (), refine=refine,
                cache=_string(raw.get("cache", geometry_files.CACHE_DIR), f"{path}.cache"),
                groups=_groups(sources, f"{path}.{source}"), source_hash=geometry_files.source_hash(sources))


def _geometry_file(name, path):
    geo = geometry_files.geometry_path(name)
    if not geo.is_file():
        shipped = ", ".join(geometry_files.shipped_geometries())
        raise ConfigError(path, f"{name!r} is neither a shipped geometry ({shipped}) nor an existing .geo file")
    return geo


def _msh_files(raw, path):
    files = [raw] if isinstance(raw, str) else raw
    if not isinstance(files, list) or not files:
        raise ConfigError(path, f"must be a .msh file or a non-empty list of them, got {_show(raw)}")
    for i, name in enumerate(files):
        where = path if isinstance(raw, str) else f"{path}[{i}]"
        if not isinstance(name, str) or not Path(name).is_file():
            raise ConfigError(where, f"no such mesh file: {name!r}")
    return tuple(files)


def _sizes(raw, path):
    if not isinstance(raw, list) or not raw:
        raise ConfigError(path, f"must be a non-empty list of target cell sizes, got {_show(raw)}")
    sizes = tuple(_number(s, f"{path}[{i}]", positive=True) for i, s in enumerate(raw))
    if any(b >= a for a, b in zip(sizes, sizes[1:])):
        raise ConfigError(path, f"must decrease (finer levels last), got {list(sizes)}")
    return sizes


def _refinements(raw, path):
    if not isinstance(raw, list) or not raw:
        raise ConfigError(path, f"must be a non-empty list of refinement counts (0 = the base mesh), got {_show(raw)}")
    counts = tuple(_integer(k, f"{path}[{i}]", low=0) for i, k in enumerate(raw))
    if any(b <= a for a, b in zip(counts, counts[1:])):
        raise ConfigError(path, f"must increase, got {list(counts)}")
    return counts


def _groups(sources, path):
    """The (name, dimension) physical groups every source defines, with a domain of dimension 2 or 3."""
    per_source = [geometry_files.physical_groups(s) for s in sources]
    groups = {name: dim for name, dim in per_source[0].items()
              if all(other.get(name) == dim for other in per_source[1:])}
    if not groups or max(groups.values()) not in (2, 3):
        raise ConfigError(path, f"{sources[0]} names no physical group of dimension 2 or 3 (the domain): "
                                "name the domain, Γ_C and Γ_D with Physical ... (\"name\")")
    return tuple(sorted(groups.items()))


def _contact(value, mesh, dim):
    """A face name on the unit square/cube, or a physical group of dimension d - 1 of a gmsh/file mesh."""
    if mesh.kind in MESH_KINDS:
        return _choice(value, "contact", FACES[dim])
    facet_groups = tuple(name for name, d in mesh.groups if d == dim - 1)
    if not facet_groups:
        raise ConfigError("contact", f"the mesh source has no physical group of dimension {dim - 1}")
    return _choice(value, "contact", facet_groups)


def _problem(raw, path, dim):
    if raw is None:
        raise ConfigError(path, "missing: give problem.exact (manufactured) or problem.f")
    _keys(raw, path, optional=("exact", "f", "g", "exact_solves"))
    coords = COORDINATES[dim]
    exact, f, g = (_expression(raw[k], f"{path}.{k}", coords + ("eps",)) if k in raw else None
                   for k in ("exact", "f", "g"))
    if exact is None and f is None:
        raise ConfigError(path, "give exact (a manufactured solution) or f (data only)")
    if exact is not None and (f is not None or g is not None):
        raise ConfigError(path, "exact determines f and g; give exact alone, or f (and g) alone")
    return Problem(exact, f, g, _exact_solves(raw, path, exact))


def _positive_part(raw, path):
    if isinstance(raw, str):
        raw = {"kind": raw}
    _keys(raw, path, optional=("kind", "delta"))
    kind = _choice(raw.get("kind", "exact"), f"{path}.kind", POSITIVE_PARTS)
    if kind == "exact":
        if "delta" in raw:
            raise ConfigError(f"{path}.delta", "only meaningful with kind: smooth")
        return PositivePart()
    delta = _expression(raw.get("delta", DEFAULT_DELTA), f"{path}.delta", ("h", "eps"))
    return PositivePart(kind, delta)


def _contact_quadrature(raw, positive_kind):
    """exact | vertex | a Gauss degree >= 1; vertex lumps the exact positive part only (the smooth one
    keeps its UFL quadrature)."""
    path = "contact_quadrature"
    if isinstance(raw, str):
        value = _choice(raw, path, CONTACT_QUADRATURES)
    else:
        value = _integer(raw, path, low=1)
    if value == "vertex" and positive_kind != "exact":
        raise ConfigError(path, "vertex lumps the exact positive part; positive_part: smooth keeps its quadrature")
    return value


def _solver(raw, path):
    _keys(raw, path, optional=("rtol", "atol", "max_it", "linear", "line_search", "on_failure",
                               "petsc_options") + SOLVER_STRATEGY_KEYS)
    opts = raw.get("petsc_options", {}) or {}
    if not isinstance(opts, dict):
        raise ConfigError(f"{path}.petsc_options", "must be a mapping of PETSc option names to values")
    solver = Solver(rtol=_number(raw.get("rtol", 1e-10), f"{path}.rtol", positive=True),
                  atol=_number(raw.get("atol", 1e-12), f"{path}.atol", positive=True),
                  max_it=_integer(raw.get("max_it", 50), f"{path}.max_it", low=1),
                  linear=_choice(raw.get("linear", "auto"), f"{path}.linear", LINEAR_SOLVERS),
                  line_search=_choice(raw.get("line_search", "bt"), f"{path}.line_search", LINE_SEARCHES),
                  on_failure=_choice(raw.get("on_failure", "continue"), f"{path}.on_failure", ON_FAILURE),
                  petsc_options=tuple((str(k).lstrip("-"), "" if v is None else str(v))
                                      for k, v in opts.items()))
    return dataclasses.replace(solver, **_solver_strategy(raw, path))


SOLVER_STRATEGY_KEYS = ("strategy", "method", "stol", "preconditioner", "linear_rtol", "linear_fallback",
                        "inexact", "continuation", "condition_max_dofs", "linear_floor")


def _solver_strategy(raw, path):
    """The robustness keys of solver: (issue 5), as Solver field values."""
    method = _choice(raw.get("method", "newtonls"), f"{path}.method", METHODS)
    if method == "newtontr" and "line_search" in raw:
        raise ConfigError(f"{path}.line_search", "only meaningful with method: newtonls")
    return dict(strategy=_choice(raw.get("strategy", "auto"), f"{path}.strategy", STRATEGIES),
                method=method,
                stol=_number(raw.get("stol", 1e-7), f"{path}.stol", low=0.0),
                preconditioner=_choice(raw.get("preconditioner", "boomeramg"), f"{path}.preconditioner",
                                       PRECONDITIONERS),
                linear_rtol=_number(raw.get("linear_rtol", 1e-10), f"{path}.linear_rtol", positive=True),
                linear_fallback=_boolean(raw.get("linear_fallback", True), f"{path}.linear_fallback"),
                inexact=_boolean(raw.get("inexact", False), f"{path}.inexact"),
                continuation=_continuation(raw.get("continuation", {}), f"{path}.continuation"),
                condition_max_dofs=_integer(raw.get("condition_max_dofs", 0), f"{path}.condition_max_dofs",
                                            low=0),
                linear_floor=_boolean(raw.get("linear_floor", False), f"{path}.linear_floor"))


def _continuation(raw, path):
    _keys(raw, path, optional=("start", "factor", "max_steps"))
    factor = _number(raw.get("factor", 0.1), f"{path}.factor", positive=True)
    if factor >= 1:
        raise ConfigError(f"{path}.factor", f"must be < 1 (eps decreases), got {factor:g}")
    return Continuation(start=_number(raw.get("start", 1.0), f"{path}.start", positive=True),
                        factor=factor,
                        max_steps=_integer(raw.get("max_steps", 20), f"{path}.max_steps", low=1))


def _output(raw, path):
    _keys(raw, path, optional=("dir", "plots", "fields", "digits"))
    return Output(dir=_string(raw.get("dir", "results"), f"{path}.dir"),
                  plots=_boolean(raw.get("plots", True), f"{path}.plots"),
                  fields=_boolean(raw.get("fields", False), f"{path}.fields"),
                  digits=_integer(raw.get("digits", 3), f"{path}.digits", low=1))


def _verification(raw, path, problem):
    _keys(raw, path, optional=("fit_levels", "tolerance", "measures", "reference_refinements",
                               "reference_epsilon", "regular"))
    data_only = isinstance(problem, dict) and "exact" not in problem
    for key in ("reference_refinements", "reference_epsilon"):
        if key in raw and not data_only:
            raise ConfigError(f"{path}.{key}", "only meaningful without problem.exact (data-only scenes)")
    measures = raw.get("measures")
    if measures is not None:
        if not isinstance(measures, list):
            raise ConfigError(f"{path}.measures", f"must be a list of {', '.join(MEASURES)}")
        measures = tuple(_choice(m, f"{path}.measures[{i}]", MEASURES) for i, m in enumerate(measures))
        if len(set(measures)) != len(measures):
            raise ConfigError(f"{path}.measures", f"lists a measure twice: {list(measures)}")
    return Verification(
        fit_levels=_integer(raw.get("fit_levels", 3), f"{path}.fit_levels", low=2),
        tolerance=_number(raw.get("tolerance", 0.1), f"{path}.tolerance", low=0.0),
        measures=measures,
        reference_refinements=_integer(raw.get("reference_refinements", 1), f"{path}.reference_refinements",
                                       low=0, high=MAX_REFERENCE_REFINEMENTS),
        reference_epsilon=_choice(raw.get("reference_epsilon", "per_level"), f"{path}.reference_epsilon",
                                  REFERENCE_EPSILONS),
        regular=_boolean(raw.get("regular", True), f"{path}.regular"))


def _expect(raw, path, problem):
    _keys(raw, path, required=("rates",), optional=("tolerance",))
    rates = raw["rates"]
    if not isinstance(rates, dict) or not rates:
        raise ConfigError(f"{path}.rates", "must be a mapping of norm to rate, e.g. {L2: 2.0, H1: 1.0}")
    data_only = isinstance(problem, dict) and "exact" not in problem
    norms = REFERENCE_NORMS if data_only else ERROR_NORMS + REFERENCE_NORMS[-2:]  # diff_* in both
    for norm in rates:
        if norm not in norms:
            scene = "a data-only scene (no exact solution)" if data_only else "a manufactured scene"
            raise ConfigError(f"{path}.rates.{norm}", f"not a rate column of {scene}; one of {', '.join(norms)}")
    return Expect(rates=tuple((norm, _number(rate, f"{path}.rates.{norm}")) for norm, rate in rates.items()),
                  tolerance=_number(raw.get("tolerance", 0.1), f"{path}.tolerance", low=0.0))


# --- the ε → 0 studies (docs/limit.md) -----------------------------------------------------------

UNUSED = {"signorini": {"alpha": "", "epsilon": "", "positive_part": "", "contact_quadrature": "", "limit": ""},
          "epsilon_sweep": {"alpha": " (give the α values as limit.alpha)",
                            "epsilon": " (the ε values are limit.epsilon)", "verification": "", "expect": ""},
          "total_error": {"alpha": " (give the α values as limit.alpha)",
                          "epsilon": " (ε = θ h^p from limit.theta and limit.exponent)",
                          "expect": " (the sub-studies differ: no single rate to expect)"}}


def _exact_solves(raw, path, exact):
    """Which problem `exact` solves: the compliance model (default) or the Signorini problem."""
    if "exact_solves" not in raw:
        return "compliance"
    solves = _choice(raw["exact_solves"], f"{path}.exact_solves", EXACT_SOLVES)
    if exact is None and solves == "signorini":
        raise ConfigError(f"{path}.exact_solves", "only meaningful with problem.exact")
    if solves == "signorini" and "eps" in exact.names:
        raise ConfigError(f"{path}.exact", "a Signorini solution cannot depend on eps")
    return solves


def _study_type(cfg, raw):
    """Validate study_type, and for the ε → 0 studies their problem and limit block."""
    kind = _choice(raw.get("study_type", "refinement"), "study_type", STUDY_TYPES)
    if kind == "refinement":
        if "limit" in raw:
            raise ConfigError("limit", "only meaningful with study_type epsilon_sweep or total_error")
        return cfg
    for key, hint in UNUSED[kind].items():
        if key in raw:
            raise ConfigError(key, f"not used by study_type {kind}{hint}")
    _signorini_problem(cfg.problem, kind)
    if kind != "total_error" and cfg.output.fields:
        raise ConfigError("output.fields", f"not written by study_type {kind} (refinement and total_error only)")
    limit = None if kind == "signorini" else _limit(raw.get("limit"), "limit", kind, cfg.dimension)
    return dataclasses.replace(cfg, study_type=kind, limit=limit)


def _signorini_problem(problem, kind):
    """The ε → 0 studies need the Signorini problem: f (and u_S on Γ_D), contact data g = 0."""
    if problem.exact is not None and problem.exact_solves != "signorini":
        raise ConfigError("problem.exact_solves", f"study_type {kind} needs a Signorini solution: "
                                                  "set exact_solves: signorini, or give f alone")
    if problem.g is not None:
        raise ConfigError("problem.g", f"study_type {kind} needs g = 0: the ε → 0 limit of "
                                       "ε∂_n u + [u]_+^α = g is a Signorini problem only then")
    if kind == "total_error" and problem.exact is None:
        raise ConfigError("problem.exact", "study_type total_error measures u_S − u_h: give u_S")


def _limit(raw, path, kind, dim):
    if raw is None:
        raise ConfigError(path, f"missing: study_type {kind} needs a limit block")
    sweep = kind == "epsilon_sweep"
    _keys(raw, path, required=("epsilon",) if sweep else ("exponent",),
          optional=("alpha", "fit_last") + (() if sweep else ("theta",)))
    alpha = _numbers(raw.get("alpha", [2.0]), f"{path}.alpha", low=1.0)
    if dim == 3 and max(alpha) > MAX_ALPHA_3D:
        raise ConfigError(f"{path}.alpha", f"must be <= 3 in 3-D (the paper's condition (5)), got {max(alpha):g}")
    fit_last = _integer(raw.get("fit_last", 3), f"{path}.fit_last", low=2)
    if sweep:
        return Limit(alpha=alpha, epsilon=_epsilons(raw["epsilon"], f"{path}.epsilon"), fit_last=fit_last)
    return Limit(alpha=alpha, theta=_number(raw.get("theta", 1.0), f"{path}.theta", positive=True),
                 exponent=_numbers(raw["exponent"], f"{path}.exponent", positive=True), fit_last=fit_last)


def _epsilons(raw, path):
    """The ε of a sweep, decreasing: a list, or a geometric range {start, stop, count}."""
    if isinstance(raw, dict):
        _keys(raw, path, required=("start", "stop", "count"))
        start = _number(raw["start"], f"{path}.start", positive=True)
        stop = _number(raw["stop"], f"{path}.stop", positive=True)
        count = _integer(raw["count"], f"{path}.count", low=2)
        if stop >= start:
            raise ConfigError(path, f"start must be larger than stop (ε decreases), got {start:g} and {stop:g}")
        return tuple(start * (stop / start) ** (k / (count - 1)) for k in range(count))
    values = _numbers(raw, path, positive=True)
    if len(values) < 2 or any(b >= a for a, b in zip(values, values[1:])):
        raise ConfigError(path, f"must be at least two decreasing values (each ε starts from the previous "
                                f"solution), got {list(values)}")
    return values


def _numbers(raw, path, low=None, positive=False):
    """A non-empty list of numbers; a single number is a list of one."""
    values = raw if isinstance(raw, list) else [raw]
    if not values:
        raise ConfigError(path, "must be a non-empty list of numbers")
    return tuple(_number(v, f"{path}[{i}]" if isinstance(raw, list) else path, low=low, positive=positive)
                 for i, v in enumerate(values))


# --- small validators ---------------------------------------------------------------------------

def _keys(raw, path, required=(), optional=()):
    """Check a mapping has the required keys and no unknown ones (with a did-you-mean)."""
    where = path or "config"
    if not isinstance(raw, dict):
        raise ConfigError(path, f"must be a mapping, got {_show(raw)}")
    for key in raw:
        if key not in required and key not in optional:
            close = difflib.get_close_matches(str(key), required + optional, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ConfigError(_join(path, key), f"unknown key in {where}{hint}")
    for key in required:
        if key not in raw:
            raise ConfigError(_join(path, key), "missing required key")


def _join(path, key):
    return f"{path}.{key}" if path else str(key)


def _show(value):
    return f"{type(value).__name__} {value!r}" if not isinstance(value, (dict, list)) else type(value).__name__


def _number(value, path, low=None, positive=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(path, f"must be a number, got {_show(value)}")
    value = float(value)
    if not math.isfinite(value):
        raise ConfigError(path, f"must be finite, got {value}")
    if positive and value <= 0:
        raise ConfigError(path, f"must be > 0, got {value:g}")
    if low is not None and value < low:
        raise ConfigError(path, f"must be >= {low:g}, got {value:g}")
    return value


def _integer(value, path, low=None, high=None):
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError(path, f"must be an integer, got {_show(value)}")
    if low is not None and value < low:
        raise ConfigError(path, f"must be >= {low}, got {value}")
    if high is not None and value > high:
        raise ConfigError(path, f"must be <= {high}, got {value}")
    return value


def _boolean(value, path):
    if not isinstance(value, bool):
        raise ConfigError(path, f"must be true or false, got {_show(value)}")
    return value


def _string(value, path, empty=False):
    if not isinstance(value, str) or (not empty and not value.strip()):
        raise ConfigError(path, f"must be a non-empty string, got {_show(value)}")
    return value


def _choice(value, path, choices):
    if value not in choices:
        raise ConfigError(path, f"{value!r} is not one of {', '.join(choices)}")
    return value


def _expression(text, path, variables):
    try:
        return expressions.parse(text, variables)
    except expressions.ExpressionError as err:
        raise ConfigError(path, str(err)) from None


# --- resolved settings ----------------------------------------------------------------------------

def to_dict(cfg):
    """The resolved config as plain YAML data, every default filled in; `from_dict` reads it back."""
    out = _plain(cfg)
    out.pop("text", None)
    out["mesh"] = _mesh_dict(cfg.mesh)
    out = {"study": out.pop("study"), "description": out.pop("description"), **out}
    if cfg.epsilon.law != "power":
        out["epsilon"].pop("exponent")  # only meaningful with law: power (rejected otherwise)
    if cfg.problem.exact is not None:  # the reference keys are for data-only scenes (rejected otherwise)
        for key in ("reference_refinements", "reference_epsilon"):
            out["verification"].pop(key)
    if cfg.expect is not None:
        out["expect"]["rates"] = dict(cfg.expect.rates)
    if cfg.solver.method != "newtonls":  # the line search is for newtonls only (rejected otherwise)
        out["solver"].pop("line_search")
    _limit_to_dict(cfg, out)
    return out


def _limit_to_dict(cfg, out):
    """Leave out what the ε → 0 study types reject: unused top-level keys, the other type's limit keys."""
    for key in UNUSED.get(cfg.study_type, {}):
        out.pop(key, None)
    if cfg.limit is not None:
        for key in (("theta", "exponent") if cfg.study_type == "epsilon_sweep" else ("epsilon",)):
            out["limit"].pop(key)


# --- YAML reading ----------------------------------------------------------------------------------

class _Loader(yaml.SafeLoader):
    """Safe YAML that rejects duplicate keys (PyYAML keeps the last one silently) and reads 1e-8
    as a number, as YAML 1.2 does (PyYAML's YAML 1.1 reads it as a string)."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            if isinstance(key_node, yaml.ScalarNode) and key_node.tag != "tag:yaml.org,2002:merge":
                if key_node.value in seen:
                    raise yaml.constructor.ConstructorError(
                        "while constructing a mapping", node.start_mark,
                        f"found duplicate key {key_node.value!r}", key_node.start_mark)
                seen.add(key_node.value)
        return super().construct_mapping(node, deep=deep)


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"), list("-+0123456789."))


def yaml_load(text):
    """YAML text -> Python data (safe: plain data only). Bad characters and excessive nesting are
    reported as YAML errors with a line and column, never as Python exceptions."""
    try:
        return yaml.load(text, Loader=_Loader)
    except yaml.reader.ReaderError as err:
        line = text.count("\n", 0, err.position)
        column = err.position - (text.rfind("\n", 0, err.position) + 1)
        character = f"#x{err.character:04x}" if isinstance(err.character, int) else repr(err.character)
        mark = yaml.Mark("config", err.position, line, column, None, None)
        raise yaml.MarkedYAMLError(problem=f"unacceptable character {character}: {err.reason}",
                                   problem_mark=mark) from None
    except RecursionError:
        raise ConfigError("", "YAML nested too deeply") from None


# --- the config hash (resume) ----------------------------------------------------------------------

NOT_HASHED = ("text", "output", "description")  # where results go and comments do not change them


def canonical(cfg):
    """The validated settings that determine a study's numbers, as plain JSON-able data."""
    return {name: value for name, value in _plain(cfg).items() if name not in NOT_HASHED}


def fingerprint(cfg):
    """sha256 of canonical(cfg): equal for configs that compute the same study."""
    return hashlib.sha256(json.dumps(canonical(cfg), sort_keys=True, default=str).encode()).hexdigest()


def _mesh_dict(mesh):
    """The mesh keys its kind accepts (groups are read from the source, not given)."""
    if mesh.kind in MESH_KINDS:
        return {"kind": mesh.kind, "refinements": list(mesh.refinements), "diagonal": mesh.diagonal}
    out = {"kind": mesh.kind}
    out.update({"geometry": mesh.geometry, "sizes": list(mesh.sizes)} if mesh.kind == "gmsh" else
               {"path": list(mesh.path)})
    if mesh.refine == "uniform":
        out.update(refine=mesh.refine, refinements=list(mesh.refinements))
    out["cache"] = mesh.cache
    return out


def _plain(value):
    if isinstance(value, expressions.Expression):
        return value.text
    if dataclasses.is_dataclass(value):
        fields = ((f.name, getattr(value, f.name)) for f in dataclasses.fields(value))
        return {name: dict(item) if name == "petsc_options" else _plain(item)  # (name, value) pairs
                for name, item in fields if item is not None}
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    return value
