"""The refinement loop: one solved and measured level per mesh of the family."""
import time
from dataclasses import dataclass, field

from mpi4py import MPI
from dolfinx import fem

from . import fields, meshes, measure, model, solver
from .meshes import DIRICHLET
from . import verification


@dataclass
class Level:
    """One level's record: mesh size, ε, solver outcome, errors, wall time."""
    index: int
    n: int
    h: float
    dofs: int
    eps: float
    outcome: solver.Outcome
    errors: dict
    time_s: float
    extra: dict = field(default_factory=dict)


def run_study(cfg, on_level=None, comm=MPI.COMM_WORLD, monitor=None, done=()):
    """Solve every level of `cfg`; call on_level(levels_so_far) after each; return the levels.
    `monitor(snes, its, fnorm)`, if given, is called at every Newton iteration (progress).
    `done`: the levels a resumed study already has, kept as they are and not solved again."""
    if cfg.study_type != "refinement":  # the Signorini limit studies (docs/limit.md)
        from . import limit
        return limit.run_study(cfg, on_level, comm, monitor)
    levels = list(done)
    if done and not done[-1].outcome.converged and cfg.solver.on_failure == "stop":
        return levels  # the study had already stopped there
    verifier = verification.Verifier(cfg, comm)
    resume_verifier(cfg, done, comm, verifier)
    for index, n in enumerate(cfg.mesh.levels):
        if index < len(done):
            continue
        levels.append(solve_level(cfg, index, n, comm, monitor, verifier))
        verification.add_rates(levels)
        if on_level is not None:
            on_level(levels)
        if not levels[-1].outcome.converged and cfg.solver.on_failure == "stop":
            break
    return levels


def resume_verifier(cfg, done, comm, verifier):
    """A resumed study solves its last converged level again, unrecorded: the successive differences
    (measure `diff`) of the next level need its u_h."""
    converged = [lv for lv in done if lv.outcome.converged]
    if converged and len(done) < len(cfg.mesh.levels) and "diff" in verifier.measures:
        index = converged[-1].index
        solve_level(cfg, index, cfg.mesh.levels[index], comm, verifier=verifier)


def solve_level(cfg, index, n, comm=MPI.COMM_WORLD, monitor=None, verifier=None):
    """Build, solve and measure the level with n cells per side (or the level's entry of mesh.levels)."""
    start = time.perf_counter()
    domain = meshes.build(cfg.mesh, cfg.contact, n, comm)
    V = fem.FunctionSpace(domain.mesh, ("Lagrange", 1))
    eps_value = cfg.epsilon(domain.h)
    eps = fem.Constant(domain.mesh, eps_value)
    u_h = fem.Function(V, name="u_h")
    forms = model.forms(cfg, domain, u_h, eps)
    bcs = [dirichlet_condition(V, domain, forms.u_exact)]
    newton = solver.NewtonSolver(forms.F, forms.J, u_h, bcs, solver.petsc_options(cfg.solver, cfg.dimension),
                                 monitor=monitor)
    outcome = newton.solve()
    newton.destroy()
    # measured even when Newton failed (kept in study.h5 for diagnosis); the table blanks them
    errors = measure.errors(u_h, forms.u_exact) if forms.u_exact is not None else {}
    elapsed = domain.mesh.comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    dofs = V.dofmap.index_map.size_global * V.dofmap.index_map_bs
    if cfg.output.fields:
        fields.write(cfg.output_dir, index, domain, u_h, forms.u_exact)
    level = Level(index, domain.n, domain.h, dofs, eps_value, outcome, errors, elapsed,
                  dict(domain.columns))
    if verifier is not None:  # Γ_C measures, reference errors (issue 4); not part of time_s
        verifier.measure(level, domain, u_h, forms)
    return level


def dirichlet_condition(V, domain, u_exact):
    """u = u_ex on Γ_D for manufactured scenes (u_ex vanishes there in the paper's setting), else 0."""
    facets = domain.facet_tags.indices[domain.facet_tags.values == DIRICHLET]
    dofs = fem.locate_dofs_topological(V, domain.mesh.topology.dim - 1, facets)
    u_D = fem.Function(V)
    if u_exact is not None:
        u_D.interpolate(fem.Expression(u_exact, V.element.interpolation_points()))
    return fem.dirichletbc(u_D, dofs)
