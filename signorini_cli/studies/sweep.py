"""ε-sweeps: the model error ||u_{ε,h} − u_{S,h}|| on fixed meshes (paper Lemma 2.5)."""
import dataclasses
import time
from dataclasses import dataclass

from mpi4py import MPI
from dolfinx import fem

from ..meshing import meshes
from ..problems import measure
from ..problems.registry import problem_of
from ..solve import solver, strategies
from .signorini import signorini_level


@dataclass
class Point:
    """One compliance solve of an ε-sweep, measured against the mesh's discrete Signorini solution."""
    n: int
    h: float
    dofs: int
    alpha: float
    eps: float
    outcome: solver.Outcome
    differences: dict
    time_s: float


@dataclass
class Sweep:
    """An ε-sweep: the VI reference Level per mesh and the Points; iterating gives every solve."""
    references: list
    points: list

    def __iter__(self):
        return iter(self.references + self.points)


def run_sweep(cfg, on_level=None, comm=MPI.COMM_WORLD, monitor=None, done=()):
    """For every mesh: the VI's u_{S,h}, then for every α the compliance u_{ε,h} down the ε list."""
    sweep = Sweep([], [])
    for index, n in enumerate(cfg.mesh.refinements):
        start = time.perf_counter()
        domain = meshes.build(cfg.mesh, cfg.contact, n, comm)
        reference, u_S = signorini_level(cfg, index, domain, start)
        sweep.references.append(reference)
        for alpha in cfg.limit.alpha:
            for point in sweep_alpha(cfg, domain, u_S, alpha):
                sweep.points.append(point)
                if on_level is not None:
                    on_level(sweep)
    return sweep


def sweep_alpha(cfg, domain, u_S, alpha):
    """Compliance solutions for decreasing ε on one mesh, each from the last converged one (strategies.descend)."""
    V = u_S.function_space
    eps = fem.Constant(domain.mesh, cfg.limit.epsilon[0])
    u_h = fem.Function(V, name="u_eps_h")
    problem_module = problem_of(cfg)
    forms = problem_module.forms(dataclasses.replace(cfg, alpha=alpha), domain, u_h, eps)
    bc = problem_module.dirichlet_condition(V, domain, forms.u_exact)
    problem = strategies.problem(forms, u_h, [bc], eps, cfg.limit.epsilon[0], cfg.dimension)
    gamma_c_dofs = fem.locate_dofs_topological(V, domain.mesh.topology.dim - 1, domain.facets())
    ds_c = domain.ds_c(measure.product_degree(V))
    solved = cfg.limit.epsilon[0]
    with strategies.newton_for(cfg.solver, problem) as newton:
        for value in cfg.limit.epsilon:
            start = time.perf_counter()
            outcome = strategies.descend(newton, problem, value, cfg.solver, solved)
            solved = value if outcome.converged else solved
            found = measure.model_differences(u_h, u_S, ds_c, gamma_c_dofs)
            elapsed = domain.mesh.comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
            yield Point(domain.n, domain.h, solver.global_dofs(V), alpha, value, outcome, found, elapsed)
