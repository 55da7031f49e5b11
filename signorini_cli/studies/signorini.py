"""The Signorini VI as a refinement study (paper eq. (8), docs/limit.md): the rate table with ε = 0,
recorded and reported as a refinement study's."""
import dataclasses
import time

from mpi4py import MPI
from dolfinx import fem

from ..meshing import meshes
from ..meshing.meshes import FACES_2D, FACES_3D
from ..problems import registry
from ..problems.registry import problem_of
from ..solve import solver
from .level import Level
from .refinement import compared, levels_of, parts, reported, summary, tables  # noqa: F401  the same record

NAME = "signorini"
UNIT = "levels"
RESUMABLE = False  # the VI's levels are not read back from study.h5
POINTS = False  # a study of its own levels or solves (a map: points, run and recorded by app/maps)


def run(cfg, on_level=None, comm=MPI.COMM_WORLD, monitor=None, done=()):
    """The VI refinement study: one Level per mesh, the rate table with ε = 0; each level starts
    from the last converged one as the strategy says (nested iteration)."""
    levels, previous = [], None
    for index, n in enumerate(cfg.mesh.refinements):
        start = time.perf_counter()
        domain = meshes.build(cfg.mesh, cfg.contact, n, comm)
        level, u_h = signorini_level(cfg, index, domain, start, previous, monitor)
        levels.append(level)
        previous = u_h if level.outcome.converged else previous
        if on_level is not None:  # it sees the level's u_h (Level.solution), which the next level lets go
            level.solution, level.scene = u_h, (domain, None)  # no ε: no compliance pressure
            on_level(levels)
            level.solution, level.scene = None, None
        if not level.outcome.converged and cfg.solver.on_failure == "stop":
            break
    return levels


def signorini_level(cfg, index, domain, start, previous=None, monitor=None):
    """(Level, u_h): the VI on `domain`, measured against u_S if given, with its contact state."""
    vi = problem_of(cfg, limit=True)
    V = vi.space(cfg, domain.mesh)
    u_h = fem.Function(V, name="u_h")
    u_exact = vi.exact_solution(cfg, domain.mesh)
    # u_S a Signorini solution, refused before solving; the quadrature degrees (data, errors) its data need
    domain = dataclasses.replace(domain, quadrature=registry.check_posed(cfg, domain, u_exact, 0.0))
    bc = vi.dirichlet_condition(V, domain, u_exact)
    outcome, forms = vi.solve(cfg, domain, u_h, bc, previous, monitor)
    errors = vi.errors(u_h, u_exact, domain.h, domain.quadrature[1]) if u_exact is not None else {}
    state = vi.contact_state(forms, u_h, domain, bc)
    extra = {"contact_nodes": state.nodes, "contact_measure": state.measure,
             "contact_force": state.force, "pressure_max": state.pressure_max}
    if u_exact is not None:
        face = (FACES_2D if cfg.dimension == 2 else FACES_3D)[cfg.contact]
        extra["pressure_L2"] = vi.pressure_error(forms, u_h, domain, bc, face)
    elapsed = domain.mesh.comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    dofs = solver.global_dofs(V)
    return Level(index, domain.n, domain.h, dofs, 0.0, outcome, errors, elapsed, extra), u_h


def title(cfg, name):
    """A one-line plot title: the variational inequality has no α and no ε."""
    return f"{name}: d = {cfg.dimension}, Signorini variational inequality (ε = 0)"
