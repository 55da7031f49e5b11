"""Problems × methods: a study reaches its function space, forms, boundary condition and errors only
through the Discretisation problem_of(cfg) returns, a problem (its PDE: space, operator, data, Γ_C side,
errors) with the method that enforces its contact condition; a new PDE or method is one new module here."""
import contextlib
import weakref
from dataclasses import dataclass

from . import compliance, elasticity, nitsche, penalty, posed, vi

# cfg.problem.pde -> the problem's module
PROBLEMS = {"poisson": compliance, "elasticity": elasticity}
# (pde, method) -> the method's module, for the pairs that exist
METHODS = {("poisson", "penalty"): penalty, ("elasticity", "penalty"): penalty, ("poisson", "nitsche"): nitsche}
# the problem's ε → 0 limit solved as a variational inequality (paper eq. (8)), by pde
LIMITS = {"poisson": vi}


@dataclass(frozen=True)
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

    def dirichlet_condition(self, V, domain, u_exact):
        return self.problem.dirichlet_condition(V, domain, u_exact)

    def errors(self, u_h, u_exact, h):
        return self.problem.errors(u_h, u_exact, h)


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


# the checks a problem's data pass before its first solve (problems/posed.py: the scalar problem's)
POSED = {"poisson": posed.check}


_passed = None  # within checked_once(): {(id(mesh), data): weak reference to the mesh they passed on}


@contextlib.contextmanager
def checked_once():
    """Within: a problem's data are checked once on each level's mesh (a map's points share their meshes
    and, but for ε and α, their data)."""
    global _passed
    _passed = {}
    try:
        yield
    finally:
        _passed = None


def check_posed(cfg, domain, u_exact, eps_value):
    """ConfigError (on every rank) when the level's problem is not posed right, where its PDE has a check."""
    if cfg.problem.pde not in POSED:
        return
    key = (id(domain.mesh), _data(cfg.problem, eps_value))
    if _passed is not None and key in _passed and _passed[key]() is domain.mesh:
        return
    POSED[cfg.problem.pde](cfg, domain, u_exact, eps_value)
    if _passed is not None:
        for gone in [k for k, mesh in _passed.items() if mesh() is None]:
            del _passed[gone]
        _passed[key] = weakref.ref(domain.mesh)


def _data(problem, eps_value):
    """What the check of a problem's data depends on: their texts, and ε where they use it."""
    texts = [e.text if e is not None else None for e in (problem.exact, problem.f, problem.g)]
    uses_eps = any(e is not None and "eps" in e.names for e in (problem.exact, problem.f, problem.g))
    defined = tuple((name, e.text) for name, e in problem.define)
    return repr((texts, defined, problem.exact_solves, eps_value if uses_eps else None))
