"""The study types, one path: `refinement` (one solved and measured level per mesh of the family),
`signorini` (the same with the VI), and the Signorini limit (docs/limit.md): `epsilon_sweep` (the model
error ||u_{ε,h} − u_{S,h}|| on fixed meshes) and `total_error` (refinement studies with ε = θ h^p beside
the VI). run_study returns the solves; results and report write them, the cli prints."""
import dataclasses
import time
from dataclasses import dataclass, field

from mpi4py import MPI
from dolfinx import fem

from . import (config, fields, meshes, measure, model, solver, stability, strategies, timing, verification,
               vi)
from .meshes import FACES_2D, FACES_3D


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
    solution: object = field(default=None, repr=False, compare=False)  # u_h, for nested iteration
    timings: dict = field(default_factory=dict, compare=False)  # t_* phases, memory (timing_columns)


def run_study(cfg, on_level=None, comm=MPI.COMM_WORLD, monitor=None, done=()):
    """Run the study of type cfg.study_type; call on_level(result_so_far) after every solve; return
    the result: a list of Levels (refinement, signorini), a Sweep or a Total.
    `monitor(snes, its, fnorm)`, if given, is called at every Newton iteration (progress).
    `done`: the levels a resumed refinement study already has, kept as they are and not solved again."""
    return STUDY_TYPES[cfg.study_type](cfg, on_level, comm, monitor, done)


def run_refinement(cfg, on_level=None, comm=MPI.COMM_WORLD, monitor=None, done=()):
    """Solve every level of `cfg` (after the levels `done`); on_level(levels_so_far) after each."""
    levels = list(done)
    if done and not done[-1].outcome.converged and cfg.solver.on_failure == "stop":
        return levels  # the study had already stopped there
    verifier = verification.Verifier(cfg, comm)
    previous = strategies.Handoff(resume_verifier(cfg, done, comm, verifier))
    for index, n in enumerate(cfg.mesh.levels):
        if index < len(done):
            continue
        levels.append(solve_level(cfg, index, n, comm, monitor, verifier, previous))
        if levels[-1].outcome.converged:
            previous = strategies.Handoff(levels[-1].solution)
        levels[-1].solution = None  # only the last converged level's u_h is kept (nested iteration)
        verification.add_rates(levels)
        if on_level is not None:
            on_level(levels)
        if not levels[-1].outcome.converged and cfg.solver.on_failure == "stop":
            break
    return levels


def resume_verifier(cfg, done, comm, verifier):
    """A resumed study solves its finished levels again, unrecorded, for what the next level needs: the
    last converged u_h, as the successive differences (measure `diff`) and nested iteration start from it.
    Nested strategies solve the whole chain again (levels 0 .. last converged, each from the one before),
    so the resumed levels start from the very same guess and give the same numbers as an uninterrupted
    run; otherwise the last converged level alone. Returns that u_h (or None)."""
    converged = [lv for lv in done if lv.outcome.converged]
    nested = cfg.solver.strategy in ("nested", "auto")
    if not converged or len(done) >= len(cfg.mesh.levels) or not (nested or "diff" in verifier.measures):
        return None
    chain = [lv for lv in done if lv.index <= converged[-1].index] if nested else converged[-1:]
    previous = None
    for lv in chain:
        again = solve_level(cfg, lv.index, cfg.mesh.levels[lv.index], comm,
                            verifier=verifier if lv is converged[-1] else None, previous=previous)
        previous = again.solution if again.outcome.converged else previous
    return previous


def solve_level(cfg, index, n, comm=MPI.COMM_WORLD, monitor=None, verifier=None, previous=None):
    """Build, solve and measure the level with n cells per side (or the level's entry of mesh.levels);
    `previous`, the last converged level's u_h (or a strategies.Handoff of it), is the initial guess of nested
    strategies.
    time_s is the level's wall time from mesh to measures; the t_* columns split it (timing.PHASES)."""
    start, phases = time.perf_counter(), timing.Phases()
    with phases("mesh"):
        domain = meshes.build(cfg.mesh, cfg.contact, n, comm)
    mesh_peak_mb = timing.peak_memory_mb(comm)
    V = fem.FunctionSpace(domain.mesh, ("Lagrange", 1))
    eps_value = cfg.epsilon(domain.h)
    eps = fem.Constant(domain.mesh, eps_value)
    u_h = fem.Function(V, name="u_h")
    forms = model.forms(cfg, domain, u_h, eps)
    bcs = [model.dirichlet_condition(V, domain, forms.u_exact)]
    problem = strategies.problem(forms, u_h, bcs, eps, eps_value, cfg.dimension)
    outcome = strategies.solve(cfg.solver, problem, previous, monitor, phases)
    dofs = solver.global_dofs(V)
    extra = dict(domain.columns, **problem_columns(cfg), **stability.report(cfg, problem, domain, outcome, dofs))
    with phases("errors"):
        # measured even when Newton failed (kept in study.h5 for diagnosis); the table blanks them
        errors = measure.errors(u_h, forms.u_exact, domain.h) if forms.u_exact is not None else {}
        level = Level(index, domain.n, domain.h, dofs, eps_value, outcome, errors, 0.0, extra, u_h)
        if verifier is not None:  # Γ_C measures, reference errors (issue 4)
            verifier.measure(level, domain, u_h, forms)
    reference_s = level.extra.get("reference_time_s") or 0.0  # its own column, in neither time_s nor t_errors
    phases.deduct("errors", reference_s)
    if cfg.output.fields:
        with phases("output"):
            fields.write(cfg.output_dir, index, domain, u_h, forms.u_exact)
    measuring = reference_s + (outcome.floor_s or 0.0)  # the linear floor too: a measurement, not the study's work
    level.time_s = comm.allreduce(time.perf_counter() - start - measuring, op=MPI.MAX)
    level.timings = timing_columns(outcome, phases, comm, mesh_peak_mb)
    return level


PROBLEM_COLUMNS = ("contact_quadrature",)


def problem_columns(cfg):
    """What every row says of the discrete problem it solved: the contact term's rule (issue 17)."""
    return {"contact_quadrature": str(cfg.contact_quadrature)}


def timing_columns(outcome, phases, comm, mesh_peak_mb):
    """The level's t_* phase times, its peak memory (at its end and right after its mesh) and, when
    measured, its linear floor and the ratio of the Newton solve to it (issue 6); t_output grows when
    results.write records the level."""
    columns = dict(phases.columns(comm), peak_memory_mb=timing.peak_memory_mb(comm),
                   peak_memory_mesh_mb=mesh_peak_mb)
    if outcome.floor_s is not None:
        columns.update(t_linear_floor=outcome.floor_s, floor_ratio=columns["t_newton"] / outcome.floor_s)
    return columns


# --- the Signorini VI as a refinement study (paper eq. (8), docs/limit.md) ---------------------------

def run_signorini(cfg, on_level=None, comm=MPI.COMM_WORLD, monitor=None, done=()):
    """The VI refinement study: one Level per mesh, the SPEC rate table with ε = 0; each level starts
    from the last converged one as the strategy says (nested iteration)."""
    levels, previous = [], None
    for index, n in enumerate(cfg.mesh.refinements):
        start = time.perf_counter()
        level, u_h = signorini_level(cfg, index, meshes.build(cfg.mesh, cfg.contact, n, comm), start,
                                     previous, monitor)
        levels.append(level)
        previous = u_h if level.outcome.converged else previous
        if on_level is not None:
            on_level(levels)
        if not level.outcome.converged and cfg.solver.on_failure == "stop":
            break
    return levels


def signorini_level(cfg, index, domain, start, previous=None, monitor=None):
    """(Level, u_h): the VI on `domain`, measured against u_S if given, with its contact state."""
    V = fem.FunctionSpace(domain.mesh, ("Lagrange", 1))
    u_h = fem.Function(V, name="u_h")
    u_exact = model.exact_solution(cfg, domain.mesh, None)
    bc = model.dirichlet_condition(V, domain, u_exact)
    outcome, forms = vi.solve(cfg, domain, u_h, bc, previous, monitor)
    errors = measure.errors(u_h, u_exact, domain.h) if u_exact is not None else {}
    state = vi.contact_state(forms, u_h, domain, bc)
    extra = {"contact_nodes": state.nodes, "contact_measure": state.measure,
             "contact_force": state.force, "pressure_max": state.pressure_max}
    if u_exact is not None:
        face = (FACES_2D if cfg.dimension == 2 else FACES_3D)[cfg.contact]
        extra["pressure_L2"] = vi.pressure_error(forms, u_h, domain, bc, face)
    elapsed = domain.mesh.comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    dofs = solver.global_dofs(V)
    return Level(index, domain.n, domain.h, dofs, 0.0, outcome, errors, elapsed, extra), u_h


# --- ε-sweeps: the model error on fixed meshes (paper Lemma 2.5) ----------------------------------

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
    forms = model.forms(dataclasses.replace(cfg, alpha=alpha), domain, u_h, eps)
    bc = model.dirichlet_condition(V, domain, forms.u_exact)
    problem = strategies.problem(forms, u_h, [bc], eps, cfg.limit.epsilon[0], cfg.dimension)
    gamma_c_dofs = fem.locate_dofs_topological(V, domain.mesh.topology.dim - 1, domain.facets())
    solved = cfg.limit.epsilon[0]
    with strategies.newton_for(cfg.solver, problem) as newton:
        for value in cfg.limit.epsilon:
            start = time.perf_counter()
            outcome = strategies.descend(newton, problem, value, cfg.solver, solved)
            solved = value if outcome.converged else solved
            found = measure.model_differences(u_h, u_S, domain.ds_c(measure.P1_DEGREE), gamma_c_dofs)
            elapsed = domain.mesh.comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
            yield Point(domain.n, domain.h, solver.global_dofs(V), alpha, value, outcome, found, elapsed)


# --- total error: refinement studies with ε = θ h^p beside the VI --------------------------------

@dataclass
class Total:
    """A total-error study: sub-study name -> (config, levels); iterating gives every level."""
    studies: dict

    def __iter__(self):
        return (level for _, levels in self.studies.values() for level in levels)


def run_total(cfg, on_level=None, comm=MPI.COMM_WORLD, monitor=None, done=()):
    """A refinement study with ε = θ h^p for every α and p, and the same study by the VI, side by side."""
    total = Total({})
    for name, sub in sub_studies(cfg):
        levels = []
        total.studies[name] = (sub, levels)

        def record(found, levels=levels):
            levels[:] = found
            if on_level is not None:
                on_level(total)

        run_study(sub, on_level=record, comm=comm)
    return total


def sub_studies(cfg):
    """(name, config) of every sub-study of a total-error study: alpha<α>-p<p> and signorini (the VI)."""
    subs = []
    for alpha in cfg.limit.alpha:
        for p in cfg.limit.exponent:
            name = f"alpha{alpha:g}-p{p:g}"
            epsilon = config.Epsilon.power(cfg.limit.theta, p)
            subs.append((name, _sub_study(cfg, name, "refinement", alpha=alpha, epsilon=epsilon)))
    subs.append(("signorini", _sub_study(cfg, "signorini", "signorini")))
    return subs


def _sub_study(cfg, name, study_type, **changes):
    """A plain study of its own type, written to <output>/<study>/<name>/."""
    output = dataclasses.replace(cfg.output, dir=str(cfg.output_dir))
    return dataclasses.replace(cfg, study=name, study_type=study_type, limit=None, output=output, **changes)


STUDY_TYPES = {"refinement": run_refinement, "signorini": run_signorini, "epsilon_sweep": run_sweep,
               "total_error": run_total}
