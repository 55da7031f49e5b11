"""Study configuration: YAML -> validated, frozen dataclasses. Every error names its key path."""
import dataclasses
import difflib
import hashlib
import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from . import expressions, geometry_files, names
from . import petsc_options as petsc

MESH_KINDS = {"unit_square": 2, "unit_cube": 3}
GEOMETRY_KINDS = ("gmsh", "file")  # meshes from a .geo geometry or from .msh files (physical groups)
REFINE = ("none", "uniform")
FACES = {2: ("left", "right", "bottom", "top"),
         3: ("left", "right", "front", "back", "bottom", "top")}
DIAGONALS = ("right", "left", "crossed")
POSITIVE_PARTS = ("exact", "smooth")
CONTACT_QUADRATURES = ("exact", "vertex")  # or an integer >= 1: a Gauss rule of that degree
# smoothing of [u]_+: delta^2/eps is the flux error off contact, so delta ~ h sqrt(eps) keeps it O(h^2)
# for every eps; docs/stability.md (make stiff) measures the laws this was chosen from
DEFAULT_DELTA = "1e-2*h*sqrt(eps)"
LINEAR_SOLVERS = ("auto", "direct", "iterative")  # auto: direct in 2-D, iterative in 3-D
LINE_SEARCHES = ("bt", "basic", "l2", "cp")
ON_FAILURE = ("continue", "stop")
STRATEGIES = ("plain", "nested", "continuation", "auto")
METHODS = ("newtonls", "newtontr")  # PETSc SNES types: line-search Newton, trust-region Newton
PRECONDITIONERS = ("boomeramg", "gamg")  # algebraic multigrid for linear: iterative
CONTACT_QUADRATURES = ("exact", "vertex")  # or an integer >= 1: a Gauss rule of that degree
TABLE_COLUMNS = ("paper", "all")  # or a list of column names (report)
MAX_ALPHA_3D = 3.0  # the paper's condition (5): 1 <= alpha <= 3 when d = 3
COORDINATES = {2: ("x", "y"), 3: ("x", "y", "z")}
# verification.measures: what a level measures beyond L2/H1 (docs/guide/verification.md)
MEASURES = names.MEASURE_KEYS
REFERENCE_EPSILONS = ("per_level", "fixed")
MAX_REFERENCE_REFINEMENTS = 3  # depth 3 is 64 (2-D) or 512 (3-D) times a level's cells
# rate columns an `expect:` block may name: exact-solution errors, errors against a reference, differences
ERROR_NORMS, REFERENCE_NORMS = names.ERROR_NORMS, names.REFERENCE_NORMS
# the ε → 0 studies: docs/limit.md; map: docs/maps.md
STUDY_TYPES = ("refinement", "signorini", "epsilon_sweep", "total_error", "map")
EXACT_SOLVES = ("compliance", "signorini")
DOCS = "docs/reference/config.md"  # where every key is described; `signorini init` prints them all


class ConfigError(ValueError):
    """A bad config value; str() starts with the key path."""

    def __init__(self, path, message):
        self.path, self.message = path, message
        super().__init__(f"{path}: {message}" if path else message)


def key(default=None, doc="", example=None, only="", internal=False):
    """A config key: its default (the one place it is written: the loader and `signorini init` read
    it here), its documentation, a value for the template where it has none, and when it applies."""
    return field(default=default, metadata={"doc": doc, "example": example, "only": only, "internal": internal})


# --- the ε law ----------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Law:
    """eps = theta h^p: the exponent p (None: epsilon.exponent) and how h^p is written."""
    p: float
    text: str  # plain text, e.g. √h
    tex: str   # LaTeX (math mode), e.g. \sqrt{h}


# the one table of eps laws: a new law is one line here
LAWS = {"theta_h": Law(1.0, "h", " h"), "theta_sqrt_h": Law(0.5, "√h", r"\sqrt{{h}}"),
        "constant": Law(0.0, "", ""), "power": Law(None, "h^{p:g}", " h^{{{p:g}}}")}
POWER_LAW = "power"  # the law with a free exponent


@dataclass(frozen=True)
class Epsilon:
    """The penalty law eps(h) = theta h^p."""
    law: str = key("theta_h", "theta_h: θh | theta_sqrt_h: θ√h | constant: θ | power: θ h^exponent")
    theta: float = key(1.0, "> 0")
    exponent: float = key(1.0, "p of law: power", only="only with law: power")

    @classmethod
    def power(cls, theta, p):
        """eps = theta h^p for any p."""
        return cls(POWER_LAW, theta, p)

    @property
    def p(self):
        """The exponent p in eps = theta h^p."""
        law = LAWS[self.law]
        return self.exponent if law.p is None else law.p

    def __call__(self, h):
        return self.theta * h ** self.p

    def formula(self):
        """The law as plain text with theta's value: 2h, √h, 0.1, h^1.5."""
        h_part = LAWS[self.law].text.format(p=self.p)
        return (f"{self.theta:g}" if self.theta != 1 or not h_part else "") + h_part

    def tex(self):
        r"""The law in LaTeX math with the symbol theta: \theta h, \theta\sqrt{h}, \theta h^{1.5}."""
        return r"\theta" + LAWS[self.law].tex.format(p=self.p)


@dataclass(frozen=True)
class Mesh:
    kind: str = key("unit_square", "unit_square | unit_cube | gmsh | file")
    refinements: tuple = key((8, 16, 32, 64), "unit_square/cube: cells per side, one level each, increasing; "
                                              "gmsh/file with refine: uniform: refinements of the base mesh")
    diagonal: str = key("right", "right | left | crossed (kind: unit_square only)")
    geometry: str = key("", "a shipped geometry (meshes/<name>.geo) or a .geo file", example="half_disk",
                        only="only with kind: gmsh")
    sizes: tuple = key((), "target cell size per level, decreasing", example=(0.2, 0.1), only="only with kind: gmsh")
    path: tuple = key((), ".msh files, one per level (the base mesh with refine: uniform)",
                      example=("mesh.msh",), only="only with kind: file")
    refine: str = key("none", "none | uniform: levels refine one base mesh (nested)",
                      only="only with kind: gmsh or file")
    cache: str = key("", "where gmsh meshes are kept (empty: meshes/cache for a shipped geometry, "
                         f"{geometry_files.USER_CACHE}/ beside a .geo file)", only="only with kind: gmsh")
    groups: tuple = key((), internal=True)        # gmsh/file: (name, dimension) of the source's physical groups
    source_hash: str = key("", internal=True)     # gmsh/file: of the .geo/.msh contents (the config hash)

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
    exact: expressions.Expression = key(None, "manufactured solution in x, y (z), eps",
                                        example="sin(2*pi*x)*(1-y)**2")
    f: expressions.Expression = key(None, "data only (no exact solution): the load", example="-10",
                                    only="only without exact")
    g: expressions.Expression = key(None, "data only: the contact data (default 0)", example="0",
                                    only="only without exact")
    exact_solves: str = key("compliance", "compliance | signorini: exact is a Signorini solution u_S, g = 0 "
                                          "(docs/limit.md)")
    define: tuple = key((), "named subexpressions, in order (later names may use earlier ones)",
                        example={"r": "sqrt(x**2 + y**2)", "t": "atan2(y, x)"}, only="optional")
    pde: str = key("poisson", "poisson (the scalar model) | elasticity (docs/elasticity.md)")
    gap: expressions.Expression = key(None, "elasticity: the initial gap g0 in x, y (z) (default 0)",
                                      only="only with pde: elasticity")
    normal: tuple = key(None, "elasticity: the obstacle's unit normal, d numbers (default: Γ_C's outward normal)",
                        only="only with pde: elasticity")


@dataclass(frozen=True)
class PositivePart:
    """[u]_+ exactly, or smoothed as (u + sqrt(u^2 + delta^2))/2 with delta an expression in h, eps."""
    kind: str = key("exact", "exact | smooth")
    delta: expressions.Expression = key(None, "δ(h, eps) > 0 (docs/stability.md)", example=DEFAULT_DELTA,
                                        only="only with kind: smooth")


@dataclass(frozen=True)
class Continuation:
    """eps-continuation: from max(start, eps) down to eps, first step eps_{k+1} = factor * eps_k."""
    start: float = key(1.0, "eps_0 = max(start, eps)")
    factor: float = key(0.1, "first eps_{k+1}/eps_k, < 1")
    max_steps: int = key(20, "SNES solves at most, per continuation")


@dataclass(frozen=True)
class Solver:
    rtol: float = key(1e-10, "success: ||F|| <= rtol * ||load without penalty||")
    atol: float = key(1e-12, "success: ||F|| <= atol")
    max_it: int = key(50, "Newton iterations per SNES solve")
    linear: str = key("auto", "auto | direct | iterative")
    line_search: str = key("bt", "bt | basic | l2 | cp (method: newtonls)")
    on_failure: str = key("continue", "continue | stop, after a level that did not converge")
    # (name, value) pairs
    petsc_options: tuple = key((), example={}, doc="extra PETSc options (no leading -) under the study's prefix")
    strategy: str = key("auto", "plain | nested | continuation | auto")
    method: str = key("newtonls", "newtonls (line search) | newtontr (trust region)")
    stol: float = key(1e-7, "success: Newton correction <= stol * ||u_h||; 0: off")
    preconditioner: str = key("boomeramg", "boomeramg | gamg, for linear: iterative")
    linear_rtol: float = key(1e-10, "CG relative tolerance")
    linear_fallback: bool = key(True, "redo a failed iterative solve with MUMPS")
    inexact: bool = key(False, "Eisenstat-Walker linear tolerances (iterative only)")
    continuation: Continuation = key(Continuation(), "eps-continuation (strategy continuation or auto)")
    condition_max_dofs: int = key(0, "> 0: estimate cond(J) on levels with at most this many dofs")
    linear_floor: bool = key(False, "also time one linear solve per level (make bench)")
    polish: int = key(3, "Newton steps after success, at most, to an error <= 1e-13 ||u_h||")


@dataclass(frozen=True)
class Verification:
    """Rate fits, verdict tolerance, extra measures, and the reference solution of data-only scenes."""
    fit_levels: int = key(3, "least-squares slope over the last k converged levels (>= 2)")
    tolerance: float = key(0.2, "verdict: inconclusive when the fitted rate's interval is wider than "
                                "± tolerance (0.2: half the smallest gap between two proven rates, 8/5 and 2)")
    measures: tuple = key(None, f"a list of {', '.join(MEASURES)}; null: every measure the scene can have")
    reference_refinements: int = key(2, "each level against its own mesh refined k times, k in 0 (none) .. 3; "
                                        "k >= 2 also checks the verdict at depth k - 1",
                                     only="only without problem.exact")
    reference_epsilon: str = key("per_level", "per_level | fixed", only="only without problem.exact")
    regular: bool = key(True, "false: u is not in W^{2,alpha+1}: every verdict is 'not covered'")


@dataclass(frozen=True)
class Expect:
    """Rates the user requires: exit status 1 when an observed fitted rate < rate - tolerance."""
    rates: tuple = key((), "norm: rate pairs", example={"L2": 2.0, "H1": 1.0})
    tolerance: float = key(0.1, "missed when observed < rate - tolerance")


@dataclass(frozen=True)
class Limit:
    """The ε → 0 studies (docs/limit.md): the α values, the ε of a sweep, the ε = θ h^p of a total-error
    study."""
    alpha: tuple = key((2.0,), "the α values")
    epsilon: tuple = key((), "epsilon_sweep: decreasing ε values, or {start, stop, count}",
                         example=(1.0, 0.1, 0.01), only="only with study_type: epsilon_sweep")
    theta: float = key(1.0, "total_error: ε = θ h^p", only="only with study_type: total_error")
    exponent: tuple = key((), "total_error: the p values", example=(1.0, 2.0), only="only with study_type: total_error")
    fit_last: int = key(3, "the fitted rate uses this many finest points")


@dataclass(frozen=True)
class Output:
    dir: str = key("results", "results folder (relative to the working directory)")
    plots: bool = key(True, "PNG/PDF convergence, work-precision and Newton plots at the end of run")
    fields: bool = key(False, "u_h, its error and the Γ_C contact indicator (elasticity: stress, von Mises, "
                              "contact pressure) per level as XDMF")
    digits: int = key(3, "digits after the point of errors, h and eps in rates.md / rates.tex")
    columns: object = key("paper", "table columns: paper | all | a list of column names")
    figure_width: float = key(0.0, "figure width in pt, or with a unit: 390pt, 5.4in (0: 345 pt, the text "
                              "width of a default LaTeX article)")


@dataclass(frozen=True)
class Element:
    """The finite element of the compliance problem: Lagrange of degree 1 or 2."""
    degree: int = key(1, "1 | 2 (2: refinement studies in 2-D, contact_quadrature a Gauss rule)")


# P2: no closed form for the contact term, so a Gauss rule on Γ_C; its degree by default (docs/elements.md
# measures it against a rule of twice the degree)
P2_CONTACT_QUADRATURE = 8


@dataclass(frozen=True)
class Material:
    """Isotropic linear elasticity: Young's modulus and Poisson's ratio (plane strain in 2-D)."""
    E: float = key(1.0, "Young's modulus, > 0")
    nu: float = key(0.3, "Poisson's ratio, in (-1, 0.5)")


@dataclass(frozen=True)
class Hertz:
    """A Hertz contact (a cylinder in 2-D, a sphere in 3-D, of radius R, against a plane): its half-width,
    peak pressure and force are reported beside Hertz's closed forms."""
    radius: float = key(None, "the radius R of the curved body (or of the rigid obstacle), > 0", example=1.0)


@dataclass(frozen=True, kw_only=True)
class Config:
    study: str = key(None, "names the output folder <output.dir>/<study>/", example="my-study")
    description: str = key("", "one line, shown by `signorini list`")
    dimension: int = key(None, "2 or 3 (default: the mesh's)", example=2)
    alpha: float = key(2.0, ">= 1; <= 3 in 3-D (the paper's condition (5)) unless outside_theory")
    outside_theory: bool = key(False, "true: run what a hypothesis check would refuse (alpha > 3 in 3-D); "
                                      "verdicts say `not covered`")
    epsilon: Epsilon = key(Epsilon(), "the penalty law eps(h)")
    mesh: Mesh = key(None, "the levels")
    contact: str = key(None, "Γ_C: a face (left right bottom top; front back in 3-D) or a mesh's physical group",
                       example="bottom")
    problem: Problem = key(None, "give exact, or f (and g)")
    positive_part: PositivePart = key(PositivePart(), "exact | smooth | {kind: smooth, delta: ...}")
    contact_quadrature: object = key("exact", "exact | vertex | an integer >= 1 (a Gauss rule of that degree); "
                                              f"default {P2_CONTACT_QUADRATURE} with element.degree 2")
    element: Element = key(Element(), "the finite element (docs/elements.md)")
    solver: Solver = key(Solver(), "Newton and linear solves (docs/guide/solvers.md)")
    output: Output = key(Output(), "where and what is written")
    verification: Verification = key(Verification(), "rate fits, verdicts, extra measures")
    expect: Expect = key(None, "rates to require: exit status 1 when missed", only="optional")
    study_type: str = key("refinement", "refinement | signorini | epsilon_sweep | total_error | map")
    map: object = key(None, "a rate map: dotted keys -> values, one refinement study per combination",
                      example={"grid": {"epsilon.theta": [0.1, 1, 10], "alpha": [1.5, 2, 3]}, "jobs": 1,
                               "ranks_per_point": 1}, only="only with study_type: map")
    limit: Limit = key(None, "the ε → 0 studies (docs/limit.md)",
                       only="only with study_type: epsilon_sweep or total_error")
    material: Material = key(None, "elasticity: {E, nu}", only="only with problem.pde: elasticity")
    hertz: Hertz = key(None, "elasticity: {radius: R}: report the contact half-width, peak pressure and force "
                             "against Hertz's (docs/guide/elasticity.md)",
                       only="only with problem.pde: elasticity and no problem.exact")
    text: str = field(default="", repr=False, compare=False, metadata={"internal": True})  # the YAML as given

    @property
    def output_dir(self):
        return Path(self.output.dir) / self.study

    @property
    def solves(self):
        """The solves the study records: one per level; an ε-sweep one VI per mesh and one per (mesh, α,
        ε); a total-error study one refinement study per (α, p) and the VI's."""
        levels = len(self.mesh.levels)
        if self.study_type == "epsilon_sweep":
            return levels * (1 + len(self.limit.alpha) * len(self.limit.epsilon))
        if self.study_type == "total_error":
            return levels * (1 + len(self.limit.alpha) * len(self.limit.exponent))
        return levels


SECTIONS = (Config, Element, Epsilon, Mesh, Problem, PositivePart, Solver, Continuation, Output, Verification,
            Expect, Limit, Material, Hertz)
REQUIRED = ("study", "mesh", "contact")  # top-level keys without a default (problem: its own message)


def default(cls, name):
    """The default of key `name` of section `cls` (its dataclass field)."""
    return _fields(cls)[name].default


def _fields(cls):
    return {f.name: f for f in dataclasses.fields(cls)}


def keys_of(cls):
    """The config keys of a section, in order (the dataclass fields that are keys)."""
    return tuple(name for name, f in _fields(cls).items() if not f.metadata.get("internal"))


def key_paths(cls=Config, prefix=""):
    """Every config key's dotted path, sections included."""
    paths = []
    for name in keys_of(cls):
        path = _join(prefix, name)
        paths.append(path)
        if _fields(cls)[name].type in SECTIONS:
            paths.extend(key_paths(_fields(cls)[name].type, path))
    return paths


# --- loading -----------------------------------------------------------------------------------

MAX_BYTES = 1 << 20  # a config is a page of YAML: 1 MiB is far beyond any real one


def apply_override(raw, item):
    """Set `a.b.c=value` in the raw mapping; the value is parsed as YAML, then validated as usual."""
    name, sep, value = item.partition("=")
    if not sep or not name.strip():
        raise ConfigError("--set", f"expected KEY=VALUE, got {item!r}")
    try:
        set_path(raw, name.strip(), yaml_load(value))
    except yaml.YAMLError as err:
        problem = getattr(err, "problem", None) or err
        raise ConfigError(f"--set {name.strip()}", f"{value!r} is not a YAML value: {problem}") from None


def set_path(raw, dotted, value):
    """raw[a][b][c] = value for dotted = "a.b.c", creating the mappings on the way."""
    parts = dotted.split(".")
    node = raw
    for i, part in enumerate(parts[:-1]):
        child = node.get(part)
        if child is not None and not isinstance(child, dict):
            raise ConfigError(".".join(parts[:i + 1]), "is not a mapping, cannot set a sub-key")
        if child is None:
            child = node[part] = {}
        node = child
    node[parts[-1]] = value


class _Section:
    """One mapping of the config read against its dataclass: an absent key takes the field's default
    (defaults are written there only), an error names the key's dotted path."""

    def __init__(self, raw, path, cls):
        self.raw, self.path, self.cls = raw, path, cls

    def get(self, name):
        return self.raw.get(name, default(self.cls, name))

    def at(self, name):
        return _join(self.path, name)

    def number(self, name, **limits):
        return _number(self.get(name), self.at(name), **limits)

    def integer(self, name, **limits):
        return _integer(self.get(name), self.at(name), **limits)

    def boolean(self, name):
        return _boolean(self.get(name), self.at(name))

    def choice(self, name, choices):
        return _choice(self.get(name), self.at(name), choices)

    def string(self, name, empty=False):
        return _string(self.get(name), self.at(name), empty=empty)

    def section(self, name):
        """A sub-mapping's raw value ({} when absent: every key at its default)."""
        return self.raw.get(name, {})


def validate(raw, folder=None):
    """Validate a raw mapping into a Config, a map's block left to config.map (loader.from_dict reads it);
    relative mesh paths are relative to `folder` (None: the working directory), and stored resolved."""
    _keys(raw, "", required=REQUIRED, optional=keys_of(Config))
    top = _Section(raw, "", Config)
    study = top.string("study")
    if "/" in study or study in (".", "..") or not study.isprintable():  # no newline, NUL, tab ...
        raise ConfigError("study", f"must be a plain folder name, got {study!r}")
    if len(study.encode()) > 255:  # NAME_MAX of Linux file systems
        raise ConfigError("study", f"must be at most 255 bytes (a folder name), got {len(study.encode())}")
    mesh = _mesh(raw["mesh"], "mesh", Path(folder or "."))
    dim = _dimension(raw.get("dimension", mesh.dimension), mesh)
    alpha = top.number("alpha", low=1.0)
    outside = top.boolean("outside_theory")
    if dim == 3 and alpha > MAX_ALPHA_3D and not outside:
        raise ConfigError("alpha", f"must be <= 3 in 3-D (the paper's condition (5)), got {alpha:g} "
                                     "(outside_theory: true runs it, with no verdict)")
    epsilon = _epsilon(top.section("epsilon"), "epsilon")
    positive = _positive_part(top.section("positive_part"), "positive_part", epsilon)
    base = Config(study=study, dimension=dim, alpha=alpha, epsilon=epsilon,
                  mesh=mesh, contact=_contact(raw["contact"], mesh, dim),
                  problem=_problem(raw.get("problem"), "problem", dim), positive_part=positive,
                  material=_material(raw, dim), hertz=_hertz(raw),
                  contact_quadrature=_contact_quadrature(top.get("contact_quadrature"), "contact_quadrature",
                                                         positive.kind),
                  solver=_solver(top.section("solver"), "solver"),
                  output=_output(top.section("output"), "output"),
                  verification=_verification(top.section("verification"), "verification", raw.get("problem")),
                  expect=_expect(raw["expect"], "expect", raw.get("problem")) if "expect" in raw else None,
                  description=top.string("description", empty=True), outside_theory=outside,
                  element=_element(top.section("element"), "element"))
    return _check_element(_study_type(_check_geometry_mesh(_elastic_verification(base, raw), raw), raw, folder), raw)


def _dimension(value, mesh):
    """2 or 3, the mesh's (the key defaults to it)."""
    dim = _integer(value, "dimension")
    if dim not in (2, 3):
        raise ConfigError("dimension", f"must be 2 or 3, got {dim}")
    if mesh.dimension != dim:
        raise ConfigError("mesh.kind", f"{mesh.kind} is {mesh.dimension}-D but dimension is {dim}")
    return dim


def _check_geometry_mesh(cfg, raw):
    """gmsh/file meshes serve refinement studies; levels that gmsh meshes one by one are not nested (on a
    curved boundary not even the same polygon), but a reference solution or successive differences move
    each level onto a finer one."""
    v, mesh = cfg.verification, cfg.mesh
    if mesh.kind in GEOMETRY_KINDS and _Section(raw, "", Config).get("study_type") not in ("refinement", "map"):
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
    _keys(raw, path, optional=keys_of(Epsilon))
    s = _Section(raw, path, Epsilon)
    law = s.choice("law", tuple(LAWS))
    if "exponent" in raw and law != POWER_LAW:
        raise ConfigError(s.at("exponent"), f"only meaningful with law: {POWER_LAW}, not {law}")
    return Epsilon(law, s.number("theta", positive=True), s.number("exponent"))


def _mesh(raw, path, folder):
    if isinstance(raw, dict) and raw.get("kind") in GEOMETRY_KINDS:
        return _geometry_mesh(raw, path, folder)
    _keys(raw, path, required=("kind", "refinements"), optional=("diagonal",))
    s = _Section(raw, path, Mesh)
    kind = s.choice("kind", tuple(MESH_KINDS) + GEOMETRY_KINDS)
    if kind != "unit_square" and "diagonal" in raw:
        raise ConfigError(s.at("diagonal"), f"only meaningful with kind: unit_square, not {kind}")
    levels = raw["refinements"]
    if not isinstance(levels, list) or not levels:
        raise ConfigError(s.at("refinements"), f"must be a non-empty list of cells per side, got {levels!r}")
    levels = tuple(_integer(n, f"{path}.refinements[{i}]", low=1) for i, n in enumerate(levels))
    for i in range(1, len(levels)):
        if levels[i] <= levels[i - 1]:
            raise ConfigError(s.at("refinements"), f"must increase, got {list(levels)}")
    return Mesh(kind, levels, s.choice("diagonal", DIAGONALS))


def _geometry_mesh(raw, path, folder):
    """mesh: {kind: gmsh, geometry, sizes} or {kind: file, path}, optionally refine: uniform + refinements."""
    kind = raw["kind"]
    source, listed = ("geometry", "sizes") if kind == "gmsh" else ("path", "path")
    _keys(raw, path, required=("kind", source, listed), optional=("refine", "refinements", "cache"))
    s = _Section(raw, path, Mesh)
    refine = s.choice("refine", REFINE)
    if kind == "gmsh":
        given = s.string("geometry")
        geometry = _resolve(given, folder) if given.endswith(".geo") else given  # else a shipped name
        sources = (_geometry_file(geometry, s.at("geometry"), given),)
        entries = _sizes(raw["sizes"], s.at("sizes"))
    else:
        entries = _msh_files(raw["path"], s.at("path"), folder)
        sources, geometry = entries, ""
    if refine == "uniform":
        if len(entries) != 1:
            raise ConfigError(s.at(listed), f"refine: uniform refines one base mesh, got {len(entries)}")
        refinements = _refinements(raw.get("refinements"), s.at("refinements"))
    elif "refinements" in raw:
        raise ConfigError(s.at("refinements"), "only meaningful with refine: uniform")
    else:
        refinements = ()
    return Mesh(kind, refinements, geometry=geometry, sizes=entries if kind == "gmsh" else (),
                path=entries if kind == "file" else (), refine=refine,
                cache=_resolve(s.string("cache", empty=True), folder) if raw.get("cache") else "",
                groups=_groups(sources, s.at(source)), source_hash=geometry_files.source_hash(sources))


def _resolve(name, folder):
    """A path relative to `folder` (the config file's), normalised; absolute paths stay."""
    return os.path.normpath(folder / name)


def _geometry_file(name, path, given):
    geo = geometry_files.geometry_path(name)
    if not geo.is_file():
        shipped = ", ".join(geometry_files.shipped_geometries())
        raise ConfigError(path, f"{given!r} is neither a shipped geometry ({shipped}) nor an existing .geo file")
    return geo


def _msh_files(raw, path, folder):
    files = [raw] if isinstance(raw, str) else raw
    if not isinstance(files, list) or not files:
        raise ConfigError(path, f"must be a .msh file or a non-empty list of them, got {_show(raw)}")
    for i, name in enumerate(files):
        where = path if isinstance(raw, str) else f"{path}[{i}]"
        if not isinstance(name, str) or not Path(folder / name).is_file():
            relative = " (relative to the config's folder)" if isinstance(name, str) and folder != Path(".") else ""
            raise ConfigError(where, f"no such mesh file: {name!r}{relative}")
    return tuple(_resolve(name, folder) for name in files)


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


def _contact_quadrature(value, path, positive_kind):
    """exact | vertex | a Gauss rule's degree >= 1; exact and vertex integrate the exact positive
    part (the smooth one keeps its UFL quadrature)."""
    if isinstance(value, int) and not isinstance(value, bool):
        return _integer(value, path, low=1)
    if value not in CONTACT_QUADRATURES:
        raise ConfigError(path, f"{value!r} is not one of {', '.join(CONTACT_QUADRATURES)} "
                                "or an integer >= 1")
    if value == "vertex" and positive_kind != "exact":
        raise ConfigError(path, "vertex lumps the exact positive part; positive_part: smooth keeps its quadrature")
    return value


def _element(raw, path):
    _keys(raw, path, optional=keys_of(Element))
    return Element(degree=_Section(raw, path, Element).integer("degree", low=1, high=2))


def _check_element(cfg, raw):
    """What P2 supports: the compliance refinement study in 2-D, its contact term by a Gauss rule (the
    exact and vertex rules integrate piecewise linear u_h), fields written only for P1 (XDMF stores the
    values at the mesh's vertices)."""
    if cfg.element.degree == 1:
        return cfg
    if cfg.study_type != "refinement":
        raise ConfigError("element.degree", f"2 is for refinement studies; study_type {cfg.study_type} solves "
                                            "the Signorini VI, whose nodal bounds u_i <= 0 are P1 only")
    if cfg.dimension != 2:
        raise ConfigError("element.degree", "2 is for 2-D meshes: the Γ_C measures of P2 (penetration, "
                                            "contact_measure) are in closed form on segments only")
    if cfg.output.fields:
        raise ConfigError("output.fields", "written for element.degree 1 only (XDMF stores vertex values)")
    if "contact_quadrature" not in raw:
        return dataclasses.replace(cfg, contact_quadrature=P2_CONTACT_QUADRATURE)
    if not isinstance(cfg.contact_quadrature, int):
        raise ConfigError("contact_quadrature", f"{cfg.contact_quadrature} integrates P1 only; with "
                                                "element.degree 2 give a Gauss rule's degree (an integer)")
    return cfg


def _problem(raw, path, dim):
    if raw is None:
        raise ConfigError(path, "missing: give problem.exact (manufactured) or problem.f")
    _keys(raw, path, optional=keys_of(Problem))
    if _choice(raw.get("pde", default(Problem, "pde")), f"{path}.pde", PDES) == "elasticity":
        return _elastic_problem(raw, path, dim)
    for name in ELASTIC_PROBLEM_KEYS:
        if name in raw:
            raise ConfigError(f"{path}.{name}", "only meaningful with problem.pde: elasticity")
    coords = COORDINATES[dim]
    defined = _define(raw.get("define", {}), f"{path}.define", coords + ("eps",))
    exact, f, g = (_expression(raw[k], f"{path}.{k}", coords + ("eps",), defined) if k in raw else None
                   for k in ("exact", "f", "g"))
    if exact is None and f is None:
        raise ConfigError(path, "give exact (a manufactured solution) or f (data only)")
    if exact is not None and (f is not None or g is not None):
        raise ConfigError(path, "exact determines f and g; give exact alone, or f (and g) alone")
    return Problem(exact, f, g, _exact_solves(raw, path, exact), tuple(defined.items()))


def _define(raw, path, variables):
    """problem.define: {name: expression}, each checked like problem.exact."""
    if not isinstance(raw, dict):
        raise ConfigError(path, "must be a mapping of name to expression, e.g. {r: \"sqrt(x**2 + y**2)\"}")
    try:
        return expressions.definitions(raw, variables)
    except expressions.ExpressionError as err:
        raise ConfigError(path, str(err)) from None


# --- linear elasticity (docs/elasticity.md) ----------------------------------------------------------

PDES = ("poisson", "elasticity")
ELASTIC_PROBLEM_KEYS = ("gap", "normal")
SCALAR_PROBLEM_KEYS = ("f", "g", "exact_solves")  # data-only scenes and the VI: the scalar problem only


def _elastic_problem(raw, path, dim):
    """problem.exact: one expression per component of u; gap g0 (an expression, default 0); normal."""
    for name in SCALAR_PROBLEM_KEYS:
        if name in raw:
            raise ConfigError(f"{path}.{name}", "only meaningful for the scalar problem (pde: poisson); "
                                                "pde: elasticity takes exact (one expression per component)")
    exact = _components(raw["exact"], f"{path}.exact", dim) if "exact" in raw else None  # None: f = 0, ĝ = 0
    gap = _expression(raw["gap"], f"{path}.gap", COORDINATES[dim]) if "gap" in raw else None
    normal = _normal(raw["normal"], f"{path}.normal", dim) if "normal" in raw else None
    return Problem(exact=exact, pde="elasticity", gap=gap, normal=normal)


def _components(value, path, dim):
    """A list of d expressions in x, y (z), eps: one per component of u."""
    if not isinstance(value, list) or len(value) != dim:
        got = f"{len(value)} components" if isinstance(value, list) else _show(value)
        raise ConfigError(path, f"must be a list of {dim} expressions (one per component of u in {dim}-D), got {got}")
    return tuple(_expression(c, f"{path}[{i}]", COORDINATES[dim] + ("eps",)) for i, c in enumerate(value))


ELASTIC_DATA_MEASURES = ("penetration", "contact_measure", "contact_force", "hertz")


def _elastic_verification(cfg, raw):
    """The physical elastic problem (no problem.exact) measures Γ_C quantities only (with a hertz block,
    Hertz's too): no reference solution and no successive differences of vector fields."""
    measures = cfg.verification.measures or ()
    if "hertz" in measures and cfg.hertz is None:
        raise ConfigError(f"verification.measures[{measures.index('hertz')}]", "hertz needs a hertz block "
                                                                                "(hertz: {radius: R})")
    if cfg.problem.pde != "elasticity" or cfg.problem.exact is not None:
        return cfg
    v, given = cfg.verification, raw.get("verification", {})
    if given.get("reference_refinements") not in (None, 0):
        raise ConfigError("verification.reference_refinements", "pde: elasticity without problem.exact has no "
                                                                "reference solution: set 0")
    default = ELASTIC_DATA_MEASURES[:3] + (("hertz",) if cfg.hertz is not None else ())
    measures = v.measures if v.measures is not None else default
    for i, m in enumerate(measures):
        if m not in ELASTIC_DATA_MEASURES:
            raise ConfigError(f"verification.measures[{i}]", f"pde: elasticity without problem.exact measures "
                                                            f"{', '.join(ELASTIC_DATA_MEASURES)}, not {m}")
    return dataclasses.replace(cfg, verification=dataclasses.replace(v, measures=measures, reference_refinements=0))


def _normal(value, path, dim):
    """A unit vector of d numbers (normalised here; zero is refused)."""
    if not isinstance(value, list) or len(value) != dim:
        raise ConfigError(path, f"must be a list of {dim} numbers, got {_show(value)}")
    n = [_number(v, f"{path}[{i}]") for i, v in enumerate(value)]
    norm = math.sqrt(sum(v * v for v in n))
    if norm == 0:
        raise ConfigError(path, "must not be zero")
    return tuple(v / norm for v in n)


def _hertz(raw):
    """hertz: {radius} for the physical elastic problem (no problem.exact)."""
    if "hertz" not in raw:
        return None
    problem = raw.get("problem")
    if not (isinstance(problem, dict) and problem.get("pde") == "elasticity" and "exact" not in problem):
        raise ConfigError("hertz", "only meaningful with problem.pde: elasticity and no problem.exact")
    _keys(raw["hertz"], "hertz", required=("radius",))
    radius = _Section(raw["hertz"], "hertz", Hertz).number("radius")
    if radius <= 0:
        raise ConfigError("hertz.radius", f"must be > 0, got {radius:g}")
    return Hertz(radius)


def _material(raw, dim):
    """material: {E, nu} for pde: elasticity (E > 0, -1 < nu < 1/2: the Lamé λ, μ finite and positive)."""
    problem = raw.get("problem")
    elastic = isinstance(problem, dict) and problem.get("pde") == "elasticity"
    if not elastic:
        if "material" in raw:
            raise ConfigError("material", "only meaningful with problem.pde: elasticity")
        return None
    given = raw.get("material", {})
    _keys(given, "material", optional=keys_of(Material))
    s = _Section(given, "material", Material)
    E, nu = s.number("E"), s.number("nu")
    if E <= 0:
        raise ConfigError("material.E", f"must be > 0, got {E:g}")
    if not -1 < nu < 0.5:
        raise ConfigError("material.nu", f"must be in (-1, 0.5) (λ and μ finite and positive), got {nu:g}")
    return Material(E, nu)


def _positive_part(raw, path, epsilon):
    if isinstance(raw, str):
        raw = {"kind": raw}
    _keys(raw, path, optional=keys_of(PositivePart))
    s = _Section(raw, path, PositivePart)
    kind = s.choice("kind", POSITIVE_PARTS)
    if kind == "exact":
        if "delta" in raw:
            raise ConfigError(s.at("delta"), "only meaningful with kind: smooth")
        return PositivePart()
    delta = _expression(raw.get("delta", DEFAULT_DELTA), s.at("delta"), ("h", "eps"))
    _check_delta(delta, s.at("delta"), epsilon)
    return PositivePart(kind, delta)


# where δ(h, eps) is checked: every h of a study lies in (0, 1] (the domains are unit-sized and meshes
# finer than 1e-6 do not fit in memory), and eps is the law's or that of an ε → 0 sweep
DELTA_H = tuple(10.0 ** -k for k in range(7))
DELTA_EPS = tuple(10.0 ** -k for k in range(0, 13, 2))


def _check_delta(delta, path, epsilon):
    """δ > 0 with δ² a positive finite number at every (h, eps) a study can meet: δ = 0 makes the
    smoothed [u]_+ non-differentiable (NaN), δ² = inf or 0 overflows or underflows."""
    for h, eps in _delta_points(epsilon):
        try:
            value = delta({"h": h, "eps": eps}, expressions.math_functions())
            ok = value > 0 and 0 < value * value < math.inf
        except (ValueError, OverflowError, ZeroDivisionError):
            value, ok = math.nan, False
        if not ok:
            raise ConfigError(path, f"must be > 0 with a finite, nonzero square for every h in (0, 1] and "
                                    f"eps > 0, got {value:g} at h = {h:g}, eps = {eps:g}")


def _delta_points(epsilon):
    """The (h, eps) where δ is checked: DELTA_H against DELTA_EPS and the law's own eps(h)."""
    for h in DELTA_H:
        try:
            own = (epsilon(h),)
        except OverflowError:  # power law with a large negative exponent: not an eps a level can have
            own = ()
        yield from ((h, eps) for eps in DELTA_EPS + own)


def _solver(raw, path):
    _keys(raw, path, optional=keys_of(Solver))
    s = _Section(raw, path, Solver)
    method = s.choice("method", METHODS)
    if method == "newtontr" and "line_search" in raw:
        raise ConfigError(s.at("line_search"), "only meaningful with method: newtonls")
    return Solver(rtol=s.number("rtol", positive=True), atol=s.number("atol", positive=True),
                  max_it=s.integer("max_it", low=1), linear=s.choice("linear", LINEAR_SOLVERS),
                  line_search=s.choice("line_search", LINE_SEARCHES), on_failure=s.choice("on_failure", ON_FAILURE),
                  petsc_options=_petsc_options(raw.get("petsc_options") or {}, s.at("petsc_options")),
                  strategy=s.choice("strategy", STRATEGIES), method=method, stol=s.number("stol", low=0.0),
                  preconditioner=s.choice("preconditioner", PRECONDITIONERS),
                  linear_rtol=s.number("linear_rtol", positive=True), linear_fallback=s.boolean("linear_fallback"),
                  inexact=s.boolean("inexact"), continuation=_continuation(s.section("continuation"),
                                                                           s.at("continuation")),
                  condition_max_dofs=s.integer("condition_max_dofs", low=0), linear_floor=s.boolean("linear_floor"),
                  polish=s.integer("polish", low=0))


def _petsc_options(raw, path):
    """(name, value) string pairs, each checked (petsc_options.check); errors name the option's key."""
    if not isinstance(raw, dict):
        raise ConfigError(path, "must be a mapping of PETSc option names to values")
    try:
        options = tuple(petsc.check(str(name).lstrip("-"), value) for name, value in raw.items())
    except petsc.OptionError as err:
        raise ConfigError(f"{path}.{err.name}", str(err)) from None
    names = [str(name).lstrip("-") for name in raw]
    for i, (key, _) in enumerate(options):  # PETSc would keep one of them, silently
        first = next(j for j, (other, _) in enumerate(options) if other == key)
        if first < i:
            raise ConfigError(f"{path}.{names[i]}", f"is {names[first]} again (PETSc option names are "
                                                    "case-insensitive, the study's prefix is implied)")
    return options


def _continuation(raw, path):
    _keys(raw, path, optional=keys_of(Continuation))
    s = _Section(raw, path, Continuation)
    factor = s.number("factor", positive=True)
    if factor >= 1:
        raise ConfigError(s.at("factor"), f"must be < 1 (eps decreases), got {factor:g}")
    return Continuation(start=s.number("start", positive=True), factor=factor,
                        max_steps=s.integer("max_steps", low=1))


def _output(raw, path):
    _keys(raw, path, optional=keys_of(Output))
    s = _Section(raw, path, Output)
    return Output(dir=s.string("dir"), plots=s.boolean("plots"), fields=s.boolean("fields"),
                  digits=s.integer("digits", low=1), columns=_columns(s.get("columns"), s.at("columns")),
                  figure_width=length(s.get("figure_width"), s.at("figure_width")))


def _columns(value, path):
    """paper | all | a non-empty list of column names (report checks the names against the table)."""
    if isinstance(value, list):
        if not value or not all(isinstance(c, str) and c for c in value):
            raise ConfigError(path, f"must be {' | '.join(TABLE_COLUMNS)} or a non-empty list of column names")
        return tuple(value)
    return _choice(value, path, TABLE_COLUMNS)


def table_columns(text, path):
    """A command-line value: paper, all, or comma-separated column names."""
    return _columns(text if text in TABLE_COLUMNS else [c.strip() for c in text.split(",")], path)


LENGTH_UNITS = {"pt": 1.0, "in": 72.27, "cm": 72.27 / 2.54, "mm": 72.27 / 25.4}  # TeX points


def length(value, path):
    """A length in TeX points from a number (pt) or a string with a unit: "390pt", "5.4in", "12cm"."""
    text = str(value).strip()
    unit = next((u for u in LENGTH_UNITS if text.endswith(u)), "")
    try:
        points = float(text[:len(text) - len(unit)]) * LENGTH_UNITS.get(unit, 1.0)
    except ValueError:
        raise ConfigError(path, f"must be a length such as 390pt or 5.4in, got {_show(value)}") from None
    if not 0 <= points <= 2000 or (points and points < 100):
        raise ConfigError(path, f"must be between 100pt and 2000pt, got {_show(value)}")
    return points


def _verification(raw, path, problem):
    _keys(raw, path, optional=keys_of(Verification))
    s = _Section(raw, path, Verification)
    data_only = isinstance(problem, dict) and "exact" not in problem
    for name in ("reference_refinements", "reference_epsilon"):
        if name in raw and not data_only:
            raise ConfigError(s.at(name), "only meaningful without problem.exact (data-only scenes)")
    measures = s.get("measures")
    if measures is not None:
        if not isinstance(measures, list):
            raise ConfigError(s.at("measures"), f"must be a list of {', '.join(MEASURES)}")
        measures = tuple(_choice(m, f"{path}.measures[{i}]", MEASURES) for i, m in enumerate(measures))
        if len(set(measures)) != len(measures):
            raise ConfigError(s.at("measures"), f"lists a measure twice: {list(measures)}")
    return Verification(fit_levels=s.integer("fit_levels", low=2), tolerance=s.number("tolerance", low=0.0),
                        measures=measures,
                        reference_refinements=s.integer("reference_refinements", low=0,
                                                        high=MAX_REFERENCE_REFINEMENTS),
                        reference_epsilon=s.choice("reference_epsilon", REFERENCE_EPSILONS),
                        regular=s.boolean("regular"))


def _expect(raw, path, problem):
    _keys(raw, path, required=("rates",), optional=keys_of(Expect))
    s = _Section(raw, path, Expect)
    rates = raw["rates"]
    if not isinstance(rates, dict) or not rates:
        raise ConfigError(s.at("rates"), "must be a mapping of norm to rate, e.g. {L2: 2.0, H1: 1.0}")
    data_only = isinstance(problem, dict) and "exact" not in problem
    norms = REFERENCE_NORMS if data_only else ERROR_NORMS + REFERENCE_NORMS[-2:]  # diff_* in both
    for norm in rates:
        if norm not in norms:
            scene = "a data-only scene (no exact solution)" if data_only else "a manufactured scene"
            raise ConfigError(f"{path}.rates.{norm}", f"not a rate column of {scene}; one of {', '.join(norms)}")
    return Expect(rates=tuple((norm, _number(rate, f"{path}.rates.{norm}")) for norm, rate in rates.items()),
                  tolerance=s.number("tolerance", low=0.0))


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
        return default(Problem, "exact_solves")
    solves = _choice(raw["exact_solves"], f"{path}.exact_solves", EXACT_SOLVES)
    if exact is None and solves == "signorini":
        raise ConfigError(f"{path}.exact_solves", "only meaningful with problem.exact")
    if solves == "signorini" and "eps" in exact.names:
        raise ConfigError(f"{path}.exact", "a Signorini solution cannot depend on eps")
    return solves


def _study_type(cfg, raw, folder=None):
    """Validate study_type, and for the ε → 0 studies their problem and limit block; a map's points."""
    kind = _Section(raw, "", Config).choice("study_type", STUDY_TYPES)
    if "map" in raw and kind != "map":
        raise ConfigError("map", "only meaningful with study_type map")
    if kind == "map":  # its block and points: config.map, which validates each point here
        return dataclasses.replace(cfg, study_type=kind)
    if kind == "refinement":
        if "limit" in raw:
            raise ConfigError("limit", "only meaningful with study_type epsilon_sweep or total_error")
        return cfg
    for key, hint in UNUSED[kind].items():
        if key in raw:
            raise ConfigError(key, f"not used by study_type {kind}{hint}")
    if cfg.problem.pde == "elasticity":
        _elastic_limit(cfg, kind)
    else:
        _signorini_problem(cfg.problem, kind)
    if kind != "total_error" and cfg.output.fields:
        raise ConfigError("output.fields", f"not written by study_type {kind} (refinement and total_error only)")
    limit = None if kind == "signorini" else _limit(raw.get("limit"), "limit", kind, cfg.dimension,
                                                            cfg.outside_theory)
    return dataclasses.replace(cfg, study_type=kind, limit=limit)


def _elastic_limit(cfg, kind):
    """The elastic Signorini problem: the physical problem (f = 0, driven by the gap g0) with u·n ≤ g0 as
    bounds on one component, so Γ_C a face with normal ± an axis (the built-in meshes' faces) and n its own."""
    if kind == "total_error":
        raise ConfigError("study_type", "total_error measures u_S − u_h: pde: elasticity has no manufactured "
                                        "Signorini solution (signorini and epsilon_sweep run it)")
    if cfg.problem.exact is not None:
        raise ConfigError("problem.exact", f"study_type {kind} with pde: elasticity solves the physical problem "
                                           "(f = 0, driven by problem.gap): give no exact solution")
    i = FACES[cfg.dimension].index(cfg.contact)  # the faces x_k = 0, x_k = 1 in the order of the axes k
    own = tuple((1.0 if i % 2 else -1.0) if k == i // 2 else 0.0 for k in range(cfg.dimension))
    if cfg.problem.normal is not None and cfg.problem.normal != own:
        raise ConfigError("problem.normal", f"study_type {kind} bounds u·n on the face's own normal {list(own)} "
                                            "(one component of u): leave normal out")


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


def _limit(raw, path, kind, dim, outside=False):
    if raw is None:
        raise ConfigError(path, f"missing: study_type {kind} needs a limit block")
    sweep = kind == "epsilon_sweep"
    _keys(raw, path, required=("epsilon",) if sweep else ("exponent",),
          optional=("alpha", "fit_last") + (() if sweep else ("theta",)))
    s = _Section(raw, path, Limit)
    alpha = _numbers(raw.get("alpha", list(default(Limit, "alpha"))), s.at("alpha"), low=1.0)
    if dim == 3 and max(alpha) > MAX_ALPHA_3D and not outside:
        raise ConfigError(f"{path}.alpha", f"must be <= 3 in 3-D (the paper's condition (5)), got {max(alpha):g}")
    fit_last = s.integer("fit_last", low=2)
    if sweep:
        return Limit(alpha=alpha, epsilon=_epsilons(raw["epsilon"], f"{path}.epsilon"), fit_last=fit_last)
    return Limit(alpha=alpha, theta=s.number("theta", positive=True),
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
    for name in raw:
        if name not in required and name not in optional:
            close = suggest(str(name), path, required + optional)
            hint = f" (did you mean {close!r}?)" if close else ""
            raise ConfigError(_join(path, name), f"unknown key in {where}{hint}")
    for name in required:
        if name not in raw:
            raise ConfigError(_join(path, name), "missing required key")


def suggest(name, path, allowed):
    """The full dotted path of the key `name` probably means: a key of that name in another section (a
    top-level `exact` is `problem.exact`), else a close key of its own section, else of another."""
    elsewhere = [p for p in key_paths() if p.rsplit(".", 1)[-1] == name]
    if elsewhere:
        return elsewhere[0]
    close = difflib.get_close_matches(name, allowed, n=1)
    if close:
        return _join(path, close[0])
    by_name = {p.rsplit(".", 1)[-1]: p for p in reversed(key_paths())}  # the shallowest path per name
    close = difflib.get_close_matches(name, list(by_name), n=1, cutoff=0.8)  # stricter: a guess afar
    return by_name[close[0]] if close else None


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


def _expression(text, path, variables, defined=None):
    try:
        return expressions.parse(text, variables, defined)
    except expressions.ExpressionError as err:
        raise ConfigError(path, str(err)) from None


# --- the template (`signorini init`) ---------------------------------------------------------------

def template():
    """A commented config with every key and its default, generated from the dataclasses (so it lists
    exactly what the loader reads). Valid as it stands; a commented key applies only where it says."""
    head = [f"# signorini config: every key with its default (described in {DOCS}).",
            "# Required keys show an example; commented keys apply only where their comment says."]
    return "\n".join(head + _template_lines(Config, 0, False)) + "\n"


def _template_lines(cls, depth, commented):
    lines = []
    for name in keys_of(cls):
        f = _fields(cls)[name]
        doc, example, only = f.metadata["doc"], f.metadata["example"], f.metadata["only"]
        off = commented or bool(only)
        lead = ("# " if off else "") + "  " * depth  # a commented block uncomments as a whole
        comment = f"  # {doc}" + (f"; {only}" if only else "")
        if f.type in SECTIONS:
            lines.append(f"{lead}{name}:".ljust(40) + comment)
            lines += _template_lines(f.type, depth + 1, off)
            continue
        value = _flow(example if example is not None else f.default)
        lines.append(f"{lead}{name}: {value}".ljust(40) + comment)
    return lines


def documented_keys(cls=Config, prefix=""):
    """(dotted path, default as YAML, description, when it applies) of every key, sections included: the
    config reference (docs/reference/config.md) is generated from these, as `signorini init` is."""
    rows = []
    for name in keys_of(cls):
        f = _fields(cls)[name]
        path = _join(prefix, name)
        doc, only = f.metadata["doc"], f.metadata["only"]
        if f.type in SECTIONS:
            rows.append((path, "", doc, only))
            rows += documented_keys(f.type, path)
        else:
            rows.append((path, _flow(f.metadata["example"] if f.default is None and f.metadata["example"]
                                     is not None else f.default), doc, only))
    return rows

def _flow(value):
    """value as one line of YAML."""
    value = list(value) if isinstance(value, tuple) else value
    text = yaml.safe_dump(value, default_flow_style=True, width=1000, allow_unicode=True, sort_keys=False)
    return text.removesuffix("\n").removesuffix("\n...").strip()


# --- resolved settings ----------------------------------------------------------------------------

def to_dict(cfg):
    """The resolved config as plain YAML data, every default filled in; `loader.from_dict` reads it back."""
    out = _plain(cfg)
    out.pop("text", None)
    out["mesh"] = _mesh_dict(cfg.mesh)
    out = {"study": out.pop("study"), "description": out.pop("description"), **out}
    if cfg.epsilon.law != POWER_LAW:
        out["epsilon"].pop("exponent")  # only meaningful with law: power (rejected otherwise)
    if cfg.problem.exact is not None:  # the reference keys are for data-only scenes (rejected otherwise)
        for key in ("reference_refinements", "reference_epsilon"):
            out["verification"].pop(key)
    if cfg.problem.pde == "elasticity":
        out["problem"].pop("exact_solves")  # a key of the scalar problem (rejected otherwise)
    if cfg.expect is not None:
        out["expect"]["rates"] = dict(cfg.expect.rates)
    out["problem"]["define"] = {name: e.text for name, e in cfg.problem.define}
    if not cfg.problem.define:
        out["problem"].pop("define")
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


def yaml_dump(data, allow_unicode=True):
    """Plain data -> block-style YAML text, keys in order (libyaml's emitter where installed: the same text,
    four times faster, which a map's points, each written as it is resolved, notice)."""
    return yaml.dump(data, Dumper=getattr(yaml, "CSafeDumper", yaml.SafeDumper), sort_keys=False,
                     allow_unicode=allow_unicode)


def yaml_load(text):
    """YAML text -> Python data (safe: plain data only). Bad characters and excessive nesting are
    reported as YAML errors with a line and column, never as Python exceptions."""
    try:
        return _compose_checked(text)
    except yaml.reader.ReaderError as err:
        line = text.count("\n", 0, err.position)
        column = err.position - (text.rfind("\n", 0, err.position) + 1)
        character = f"#x{err.character:04x}" if isinstance(err.character, int) else repr(err.character)
        mark = yaml.Mark("config", err.position, line, column, None, None)
        raise yaml.MarkedYAMLError(problem=f"unacceptable character {character}: {err.reason}",
                                   problem_mark=mark) from None
    except RecursionError:
        raise ConfigError("", "YAML nested too deeply") from None


def _compose_checked(text):
    """Compose the YAML, check its expanded size, then build the Python data."""
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
        _check_size(node)
        return loader.construct_document(node) if node is not None else None
    finally:
        loader.dispose()


MAX_NODES = 100_000  # values in a config once aliases are expanded: real ones have a few hundred


def _check_size(root):
    """Refuse YAML whose aliases expand to more than MAX_NODES values (a "billion laughs" bomb
    composes in a few nodes but expands exponentially where the config is hashed or printed) or
    refer to themselves. Counted on the composed nodes, each node once: time and memory stay linear."""
    sizes, open_nodes = {}, set()

    def size(node):
        if id(node) in sizes:
            return sizes[id(node)]
        if id(node) in open_nodes:
            raise ConfigError("", "YAML alias refers to itself (a recursive structure)")
        open_nodes.add(id(node))
        children = node.value if isinstance(node, yaml.SequenceNode) else \
            [n for pair in node.value for n in pair] if isinstance(node, yaml.MappingNode) else []
        total = 1 + sum(size(child) for child in children)
        if total > MAX_NODES:
            raise ConfigError("", f"YAML expands to more than {MAX_NODES} values (aliases of aliases?)")
        open_nodes.discard(id(node))
        sizes[id(node)] = total
        return total

    if root is not None:
        size(root)


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
        out = {"kind": mesh.kind, "refinements": list(mesh.refinements)}
        return dict(out, diagonal=mesh.diagonal) if mesh.kind == "unit_square" else out
    out = {"kind": mesh.kind}
    out.update({"geometry": mesh.geometry, "sizes": list(mesh.sizes)} if mesh.kind == "gmsh" else
               {"path": list(mesh.path)})
    if mesh.refine == "uniform":
        out.update(refine=mesh.refine, refinements=list(mesh.refinements))
    out["cache"] = mesh.cache
    return out


def _derived(section):
    """The fields of a section derived from its keys (a map's resolved points): not settings themselves."""
    return {f.name for f in dataclasses.fields(section) if f.metadata.get("derived")}


def _plain(value):
    if isinstance(value, expressions.Expression):
        return value.text
    if dataclasses.is_dataclass(value):
        fields = ((f.name, getattr(value, f.name)) for f in dataclasses.fields(value))
        return {name: dict(item) if name == "petsc_options" else _plain(item)  # (name, value) pairs
                for name, item in fields if item is not None and name not in _derived(value)}
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    return value
