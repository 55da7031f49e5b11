"""The config's schema: one frozen dataclass per section, each key's default, documentation and when it
applies (docs/reference/config.md and `signorini init` are generated from it), the ε laws."""
import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

from . import expressions, geometry_files, names

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
TABLE_COLUMNS = ("paper", "all")  # or a list of column names (report)
MAX_ALPHA_3D = 3.0  # the paper's condition (5): 1 <= alpha <= 3 when d = 3
COORDINATES = {2: ("x", "y"), 3: ("x", "y", "z")}
# verification.measures: what a level measures beyond L2/H1 (docs/guide/verification.md)
MEASURES = names.MEASURE_KEYS
REFERENCE_EPSILONS = ("per_level", "fixed")
MAX_REFERENCE_REFINEMENTS = 3  # depth 3 is 64 (2-D) or 512 (3-D) times a level's cells
# rate columns an `expect:` block may name: exact-solution errors, errors against a reference, differences
ERROR_NORMS, REFERENCE_NORMS = names.ERROR_NORMS, names.REFERENCE_NORMS
DOCS = "docs/reference/config.md"  # where every key is described; `signorini init` prints them all


class ConfigError(ValueError):
    """A bad config value; str() starts with the key path."""

    def __init__(self, path, message):
        self.path, self.message = path, message
        super().__init__(f"{path}: {message}" if path else message)


def key(default=None, doc="", example=None, only="", internal=False, hashed_at_default=True, required=False):
    """A config key: its default (the one place it is written: the loader and `signorini init` read
    it here), its documentation, a value for the template where it has none, and when it applies.
    required: the loader refuses a config without it (where it applies), so the reference shows no default.
    hashed_at_default=False: a key added after results were recorded enters the config hash only when it
    differs from its default, so those results still resume."""
    return field(default=default, metadata={"doc": doc, "example": example, "only": only, "internal": internal,
                                            "hashed_at_default": hashed_at_default, "required": required})


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
    kind: str = key("unit_square", "unit_square | unit_cube | gmsh | file", required=True)
    refinements: tuple = key((8, 16, 32, 64), "unit_square/cube: cells per side, one level each, increasing; "
                                              "gmsh/file with refine: uniform: refinements of the base mesh",
                             required=True)
    diagonal: str = key("right", "right | left | crossed (kind: unit_square only)")
    geometry: str = key("", "a shipped geometry (meshes/<name>.geo) or a .geo file", example="half_disk",
                        only="only with kind: gmsh", required=True)
    sizes: tuple = key((), "target cell size per level, decreasing", example=(0.2, 0.1), only="only with kind: gmsh",
                       required=True)
    path: tuple = key((), ".msh files, one per level (the base mesh with refine: uniform)",
                      example=("mesh.msh",), only="only with kind: file", required=True)
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
    pde: str = key("poisson", "{choices}")  # the registered problems, each with its DOC (config/units.py)
    method: str = key("penalty", "how the contact condition enters the discrete problem: {choices}",
                      hashed_at_default=False)
    gap: expressions.Expression = key(None, "elasticity: the initial gap g0 in x, y (z) (default 0)",
                                      only="only with pde: elasticity")
    normal: tuple = key(None, "elasticity: the obstacle's unit normal, d numbers (default: Γ_C's outward normal)",
                        only="only with pde: elasticity")
    hertz_radius: float = key(None, "elasticity: the radius R of a Hertz contact (a cylinder in 2-D, a sphere in "
                                    "3-D): its half-width, peak pressure and force beside Hertz's (data only)",
                              example=1.0, only="only with pde: elasticity and no exact")


@dataclass(frozen=True)
class PositivePart:
    """[u]_+ exactly, or smoothed as (u + sqrt(u^2 + delta^2))/2 with delta an expression in h, eps."""
    kind: str = key("exact", "exact | smooth")
    delta: expressions.Expression = key(None, f"δ(h, eps) > 0, default {DEFAULT_DELTA} (docs/stability.md)",
                                        example=DEFAULT_DELTA,
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
    rates: tuple = key((), "norm: rate pairs", example={"L2": 2.0, "H1": 1.0}, required=True)
    tolerance: float = key(0.1, "missed when observed < rate - tolerance")


@dataclass(frozen=True)
class Limit:
    """The ε → 0 studies (docs/limit.md): the α values, the ε of a sweep, the ε = θ h^p of a total-error
    study."""
    alpha: tuple = key((2.0,), "the α values")
    epsilon: tuple = key((), "epsilon_sweep: decreasing ε values, or {start, stop, count}",
                         example=(1.0, 0.1, 0.01), only="only with study_type: epsilon_sweep", required=True)
    theta: float = key(1.0, "total_error: ε = θ h^p", only="only with study_type: total_error")
    exponent: tuple = key((), "total_error: the p values", example=(1.0, 2.0), only="only with study_type: total_error",
                          required=True)
    fit_last: int = key(3, "the fitted rate uses this many finest points")


@dataclass(frozen=True)
class Output:
    dir: str = key("results", "results folder (relative to the working directory)")
    plots: bool = key(True, "PNG/PDF convergence, work-precision and Newton plots at the end of run")
    fields: bool = key(False, "u_h, its error and the Γ_C contact indicator per level as XDMF")
    digits: int = key(3, "digits after the point of errors, h and eps in rates.md / rates.tex")
    columns: object = key("paper", "table columns: paper | all | a list of column names")
    figure_width: float = key(0.0, "figure width in pt, or with a unit: 390pt, 5.4in (0: 345 pt, the text "
                              "width of a default LaTeX article)")


@dataclass(frozen=True)
class Element:
    """The finite element of the compliance problem: Lagrange of degree 1 or 2."""
    degree: int = key(1, "1 | 2 (2: refinement studies, contact_quadrature exact or a Gauss rule)")


@dataclass(frozen=True)
class Map:
    """A rate map (study_type: map, docs/maps.md): the grid (dotted key -> values), explicit points, local
    workers and MPI ranks per point; `studies` are the points' validated configs, in point order."""
    grid: dict = key(None, "dotted key -> values; the map is every combination (last key fastest)",
                     example={"epsilon.theta": [0.1, 1, 10], "alpha": [1.5, 2, 3]})
    points: tuple = key((), "explicit combinations as well, after the grid's: a list of {dotted key: value}",
                        example=({"alpha": 4, "epsilon.law": "constant"},))
    jobs: int = key(1, "local workers: jobs > 1 runs the map again under `mpirun -n jobs`")
    ranks_per_point: int = key(1, "under mpirun: COMM_WORLD split into groups of this many ranks")
    studies: tuple = field(default=(), repr=False, compare=False, metadata={"internal": True, "derived": True})
    values: tuple = field(default=(), repr=False, compare=False, metadata={"internal": True, "derived": True})

    @property
    def varied(self):
        """The varied keys, grid first, in the order given: the columns of map.csv."""
        keys = list(self.grid)
        for point in self.points:
            keys += [key for key in point if key not in keys]
        return tuple(keys)


@dataclass(frozen=True, kw_only=True)
class Config:
    study: str = key(None, "names the output folder <output.dir>/<study>/", example="my-study", required=True)
    description: str = key("", "one line, shown by `signorini list`")
    dimension: int = key(None, "2 or 3 (default: the mesh's)", example=2)
    alpha: float = key(2.0, ">= 1; <= 3 in 3-D (the paper's condition (5)) unless outside_theory")
    outside_theory: bool = key(False, "true: run what a hypothesis check would refuse (alpha > 3 in 3-D); "
                                      "verdicts say `not covered`")
    epsilon: Epsilon = key(Epsilon(), "the penalty law eps(h)")
    mesh: Mesh = key(None, "the levels", required=True)
    contact: str = key(None, "Γ_C: a face (left right bottom top; front back in 3-D) or a mesh's physical group",
                       example="bottom", required=True)
    problem: Problem = key(None, "give exact, or f (and g)", required=True)
    positive_part: PositivePart = key(PositivePart(), "exact | smooth | {kind: smooth, delta: ...}")
    contact_quadrature: object = key("exact", "exact | vertex | an integer >= 1 (a Gauss rule of that degree); "
                                              "default exact (P2: each facet cut at the zeros of its quadratic)")
    element: Element = key(Element(), "the finite element (docs/elements.md)")
    solver: Solver = key(Solver(), "Newton and linear solves (docs/guide/solvers.md)")
    output: Output = key(Output(), "where and what is written")
    verification: Verification = key(Verification(), "rate fits, verdicts, extra measures")
    expect: Expect = key(None, "rates to require: exit status 1 when missed", only="optional")
    study_type: str = key("refinement", "{choices}")
    map: Map = key(None, "a rate map: one refinement study per point (grid or points, or both)",
                   only="only with study_type: map", required=True)
    limit: Limit = key(None, "the ε → 0 studies (docs/limit.md)",
                       only="only with study_type: epsilon_sweep or total_error", required=True)
    text: str = field(default="", repr=False, compare=False, metadata={"internal": True})  # the YAML as given
    # (key, section) pairs: the top-level sections a problem, method or study type registers (material)
    sections: tuple = field(default=(), repr=False, metadata={"internal": True})

    def __getattr__(self, name):
        """A registered section by its key (cfg.material); only called for names that are not fields."""
        if name != "sections":  # not yet set while a copy or unpickling builds the object
            for section_key, section in self.sections:
                if section_key == name:
                    return section
        raise AttributeError(f"{type(self).__name__!r} has no key or section {name!r}")

    @property
    def output_dir(self):
        return Path(self.output.dir) / self.study

    @property
    def solves(self):
        """The solves the study records: one per level; with a limit block also one VI per mesh and one
        solve per (mesh, α, value), its values the ε of a sweep or the exponents p of a total-error study
        (a limit block lists one of the two, the other is empty)."""
        levels = len(self.mesh.levels)
        if self.limit is None:
            return levels
        return levels * (1 + len(self.limit.alpha) * (len(self.limit.epsilon) + len(self.limit.exponent)))


@dataclass(frozen=True)
class UnitSection:
    """A top-level section a problem, method or study type brings (material): its key, dataclass and doc."""
    key: str
    cls: type
    doc: str


# the core sections (a problem, method or study type registers its own: config/units.py)
SECTIONS = (Config, Element, Epsilon, Mesh, Problem, PositivePart, Solver, Continuation, Output, Verification,
            Expect, Limit, Map)
REQUIRED = ("study", "mesh", "contact")  # top-level keys without a default (problem: its own message)


def default(cls, name):
    """The default of key `name` of section `cls` (its dataclass field)."""
    return fields_of(cls)[name].default


def fields_of(cls):
    return {f.name: f for f in dataclasses.fields(cls)}


def keys_of(cls):
    """The config keys of a section, in order (the dataclass fields that are keys)."""
    return tuple(name for name, f in fields_of(cls).items() if not f.metadata.get("internal"))
