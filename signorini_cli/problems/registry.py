"""Problems × methods: a study reaches its function space, forms, boundary condition and errors only
through the Discretisation problem_of(cfg) returns, a problem (its PDE: space, operator, data, Γ_C side,
errors) with the method that enforces its contact condition; a new PDE or method is one new module here."""
import contextlib
import dataclasses

from ..config import MESH_KINDS
from ..meshing import meshes
from . import compliance, elastic_vi, elasticity, element, nitsche, penalty, posed, vi

# cfg.problem.pde -> the problem's module
PROBLEMS = {"poisson": compliance, "elasticity": elasticity}
# (pde, method) -> the method's module, for the pairs that exist
METHODS = {("poisson", "penalty"): penalty, ("elasticity", "penalty"): penalty, ("poisson", "nitsche"): nitsche}
# the problem's ε → 0 limit solved as a variational inequality (paper eq. (8)), by pde
LIMITS = {"poisson": vi, "elasticity": elastic_vi}


@dataclasses.dataclass(frozen=True)
class Discretisation:
    """A problem and the method that enforces its contact condition: what a study solves."""
    problem: object
    method: object

    def space(self, cfg, msh):
        return self.problem.space(cfg, msh)

    def epsilon(self, cfg, h):
        """ε on a mesh of size h: the law's for a method with ε, 0 for one without (as the VI's)."""
        return cfg.epsilon(h) if self.method.EPSILON else 0.0

    def continued(self, eps):
        """The Constant the solver may continue in (ε-continuation): eps for a method with ε, else None."""
        return eps if self.method.EPSILON else None

    def forms(self, cfg, domain, u_h, eps):
        """The level's Forms: the problem's operator and data with the method's contact term."""
        return self.method.forms(cfg, self.problem.boundary(cfg, domain, u_h, eps), eps)

    def exact_solution(self, cfg, msh, eps):
        return self.problem.exact_solution(cfg, msh, eps)

    def dirichlet_condition(self, V, domain, u_exact):
        return self.problem.dirichlet_condition(V, domain, u_exact)

    def errors(self, u_h, u_exact, h, degree=None):
        return self.problem.errors(u_h, u_exact, h, degree)


def problem_of(cfg, limit=False):
    """The Discretisation of cfg's problem by its method; with `limit`, the module of its Signorini
    variational inequality (paper eq. (8))."""
    if limit:
        return LIMITS[cfg.problem.pde]
    return Discretisation(PROBLEMS[cfg.problem.pde], METHODS[cfg.problem.pde, cfg.problem.method])


def method_of(cfg):
    """The module of cfg's contact method."""
    return METHODS[cfg.problem.pde, cfg.problem.method]


def expected(cfg, norm):
    """The rate cfg's method proves for the error column `norm` (analysis.rates.Expected)."""
    return method_of(cfg).expected(cfg, norm)


# the checks a problem's data pass before its first solve (problems/posed.py)
POSED = {"poisson": posed.check, "elasticity": posed.check_elastic}


_passed = None  # within checked_once(): (mesh family, data) -> the data's Profile on the family's coarsest mesh


@contextlib.contextmanager
def checked_once():
    """Within (a study, a map: re-entrant): a problem's data are checked at the cells' quadrature points, their
    load for settling and their Profile taken, once per mesh family, on its coarsest mesh (a built-in grid's
    at most CHECK_N: what a check at interior points can find there, it finds on any level); at the vertices
    and on Γ_C on every level (where a finer level's new vertices may meet a singularity)."""
    global _passed
    if _passed is not None:
        yield
        return
    _passed = {}
    try:
        yield
    finally:
        _passed = None


def check_posed(cfg, domain, u_exact, eps_value):
    """ConfigError (on every rank) when the level's problem is not posed right: every path that solves calls
    it before its first solve on a mesh (refinement levels, map points, the VI, ε-sweeps, total error).
    Returns the level's quadrature degrees (data, errors) the data need (posed.Profile.degrees)."""
    key = (_family(cfg), _data(cfg.problem, eps_value))
    coarsest = None
    if _passed is None or key not in _passed:  # the cells' checks: on the family's coarsest mesh
        first = _checked_level(cfg.mesh)
        coarsest = domain if domain.n == first else meshes.build(cfg.mesh, cfg.contact, first, domain.mesh.comm)
    found = POSED[cfg.problem.pde](cfg, domain, u_exact, eps_value, coarsest=coarsest)
    if _passed is not None:
        found = _passed.setdefault(key, found)
    low = (compliance.QUADRATURE_DEGREE, element.error_degree(cfg.element.degree, domain.h, domain.mesh.topology.dim))
    return low if found is None else found.degrees(domain.h, *low)


# The cells' checks and the Profile evaluate the data at every Gauss rule's points of every cell (~3300 per
# tetrahedron, ~260 per triangle): their cost grows with the mesh (3-D: 1.5 s at N = 8, 11 s at 16, 100 s at
# 32). A built-in grid of any N belongs to the family (the same domain and Γ_C), so they run on the coarsest
# level but at most CHECK_N[d]; a Profile taken there scales to every level as it would from the coarsest.
CHECK_N = {2: 128, 3: 8}


def _checked_level(mesh_cfg):
    """The family member the cells' checks run on: the coarsest level, on a built-in grid at most CHECK_N."""
    first = mesh_cfg.levels[0]
    return min(first, CHECK_N[MESH_KINDS[mesh_cfg.kind]]) if mesh_cfg.kind in MESH_KINDS else first


def _family(cfg):
    """The mesh family a level belongs to: its mesh settings but the list of levels, and Γ_C."""
    return repr((dataclasses.replace(cfg.mesh, **{cfg.mesh.level_key: ()}), cfg.contact))


def _data(problem, eps_value):
    """What the check of a problem's data depends on: their texts, and ε where they use it."""
    given = _expressions(problem.exact) + [problem.f, problem.g, problem.gap]
    texts = [e.text if e is not None else None for e in given]
    uses_eps = any(e is not None and "eps" in e.names for e in given)
    defined = tuple((name, e.text) for name, e in problem.define)
    return repr((texts, defined, problem.exact_solves, eps_value if uses_eps else None))


def _expressions(exact):
    """The exact solution's expressions: one (scalar) or one per component (elasticity)."""
    return list(exact) if isinstance(exact, tuple) else [exact]
