"""The refinement study: one solved and measured level per mesh of the family; its rate table, verdict
and convergence figures."""
import dataclasses
import time

import numpy as np
from mpi4py import MPI
from dolfinx import fem

from ..meshing import meshes
from ..problems import registry
from ..problems.registry import problem_of
from ..solve import solver, strategies, transfer
from ..system import timing
from ..analysis import verdict
from . import fields, stability, verification
from .level import Figure, Level, Table, rate_table, work_precision_rows

NAME = "refinement"
UNIT = "levels"  # what status.txt and the progress lines count
RESUMABLE = True  # --resume continues after the levels in study.h5
POINTS = False  # a study of its own levels or solves (a map: points, run and recorded by app/maps)


def run(cfg, on_level=None, comm=MPI.COMM_WORLD, monitor=None, done=()):
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
        if on_level is not None:  # it sees the level's u_h (Level.solution) before it is let go
            on_level(levels)
        levels[-1].solution, levels[-1].scene = None, None  # only the last converged u_h is kept (nested iteration)
        if not levels[-1].outcome.converged and cfg.solver.on_failure == "stop":
            break
    return levels


def resume_verifier(cfg, done, comm, verifier):
    """What the next level of a resumed study needs of its finished ones: the last converged u_h, as the
    successive differences (measure `diff`) and nested iteration start from it. Stored by the run that
    solved it (Level.solution: its dofs' points and values), it is put back on its own mesh, the very
    function an uninterrupted run hands on; else the finished levels are solved again, unrecorded (nested
    strategies the whole chain, levels 0 .. last converged, each from the one before, so the resumed levels
    start from the same guess; otherwise the last converged level alone). Returns that u_h (or None)."""
    converged = [lv for lv in done if lv.outcome.converged]
    nested = cfg.solver.strategy in ("nested", "auto")
    if not converged or len(done) >= len(cfg.mesh.levels) or not (nested or "diff" in verifier.measures):
        return None
    if converged[-1].solution is not None:
        u_h = stored_function(cfg, converged[-1].solution, comm, on_mesh="diff" in verifier.measures)
        converged[-1].solution = None  # the record's copy: u_h holds it now
        if u_h is not None:
            verifier.previous = u_h if "diff" in verifier.measures else None
            return u_h
    chain = [lv for lv in done if lv.index <= converged[-1].index] if nested else converged[-1:]
    previous = None
    for lv in chain:
        again = solve_level(cfg, lv.index, cfg.mesh.levels[lv.index], comm,
                            verifier=verifier if lv is converged[-1] else None, previous=previous)
        previous = again.solution if again.outcome.converged else previous
    return previous


def stored_function(cfg, stored, comm, on_mesh=True):
    """The stored u_h (points, values) on its level's mesh built again, each dof matched to the stored
    point it equals bit for bit (the family builds the same points on any partition); None (on every
    rank) when a dof has none (the mesh is not the one it was stored on). Without `on_mesh`, a P1 u_h on
    a Kuhn grid is handed on as its grid values (transfer.GridValues: the same initial guess, no mesh)."""
    n = cfg.mesh.levels[stored.index]
    if not on_mesh and meshes.kuhn(cfg.mesh) and on_grid(stored.points, n, cfg.dimension):
        held = len(stored.points) if comm.rank == 0 else 0  # every rank has all of it: rank 0 hands it on
        return transfer.GridValues(n, stored.points[:held], stored.values[:held])
    domain = meshes.build(cfg.mesh, cfg.contact, n, comm)
    u_h = fem.Function(problem_of(cfg).space(cfg, domain.mesh), name="u_h")
    match = matching_points(stored.points, u_h.function_space.tabulate_dof_coordinates())
    if not comm.allreduce(match is not None, op=MPI.LAND):
        return None
    u_h.x.array[:] = stored.values[match].ravel()
    return u_h


def on_grid(points, n, dim):
    """Whether `points` (m, 3) are the (n + 1)^dim points of the grid with n cells per side (a P1 u_h's dofs)."""
    scaled = points[:, :dim] * n
    return len(points) == (n + 1)**dim and np.allclose(scaled, np.rint(scaled), rtol=0, atol=1e-8)


def matching_points(points, x):
    """For each row of x (m, 3) the index of the equal row of points (n, 3), or None where one has none:
    both sorted together (lexsort), an equal stored point sorts right before each of x's."""
    both = np.concatenate((points, x))
    mine = np.r_[np.zeros(len(points), dtype=bool), np.ones(len(x), dtype=bool)]
    order = np.lexsort((mine,) + tuple(both.T[::-1]))
    at = np.flatnonzero(mine[order])  # where x's points sit in the sorted order
    if len(at) and at[0] == 0:
        return None
    before = order[at - 1]
    if mine[before].any() or not np.array_equal(both[before], both[order[at]]):
        return None
    match = np.empty(len(x), dtype=np.int64)
    match[order[at] - len(points)] = before
    return match


def solve_level(cfg, index, n, comm=MPI.COMM_WORLD, monitor=None, verifier=None, previous=None):
    """Build, solve and measure the level with n cells per side (or the level's entry of mesh.levels);
    `previous`, the last converged level's u_h (or a strategies.Handoff of it), is the initial guess of nested
    strategies.
    time_s is the level's wall time from mesh to measures; the t_* columns split it (timing.PHASES)."""
    start, phases = time.perf_counter(), timing.Phases()
    with phases("mesh"):
        domain = meshes.build(cfg.mesh, cfg.contact, n, comm)
    mesh_peak_mb = timing.peak_memory_mb(comm)
    discretisation = problem_of(cfg)
    V = discretisation.space(cfg, domain.mesh)
    eps_value = discretisation.epsilon(cfg, domain.h)
    eps = fem.Constant(domain.mesh, eps_value)
    u_h = fem.Function(V, name="u_h")
    # refused before its first solve; else the quadrature degrees its data need
    domain = dataclasses.replace(domain, quadrature=registry.check_posed(cfg, domain, None, eps_value))
    forms = discretisation.forms(cfg, domain, u_h, eps)
    bcs = [discretisation.dirichlet_condition(V, domain, forms.u_exact)]
    problem = strategies.problem(forms, u_h, bcs, discretisation.continued(eps), eps_value, cfg.dimension)
    outcome = strategies.solve(cfg.solver, problem, previous, monitor, phases)
    dofs = solver.global_dofs(V)
    extra = dict(domain.columns, **problem_columns(cfg), **stability.report(cfg, problem, forms.trace, outcome, dofs))
    with phases("errors"):
        # measured even when Newton failed (kept in study.h5 for diagnosis); the table blanks them
        errors = discretisation.errors(u_h, forms.u_exact, domain.h, domain.quadrature[1]) \
            if forms.u_exact is not None else {}
        level = Level(index, domain.n, domain.h, dofs, eps_value, outcome, errors, 0.0, extra, u_h,
                      scene=(domain, forms))
        if verifier is not None:  # Γ_C measures, reference errors
            verifier.measure(level, domain, u_h, forms)
    reference_s = level.extra.get("reference_time_s") or 0.0  # its own column, in neither time_s nor t_errors
    phases.deduct("errors", reference_s)
    if cfg.output.fields:
        with phases("output"):
            elastic = (cfg, forms, eps_value) if forms.gap is not None else None
            fields.write(cfg.output_dir, index, domain, u_h, forms.u_exact, elastic)
    measuring = reference_s + (outcome.floor_s or 0.0)  # the linear floor too: a measurement, not the study's work
    level.time_s = comm.allreduce(time.perf_counter() - start - measuring, op=MPI.MAX)
    level.timings = timing_columns(outcome, phases, comm, mesh_peak_mb)
    return level


def problem_columns(cfg):
    """What every row says of the discrete problem it solved: the contact term's rule."""
    return {"contact_quadrature": str(cfg.contact_quadrature)}


def timing_columns(outcome, phases, comm, mesh_peak_mb):
    """The level's t_* phase times, its peak memory (at its end and right after its mesh) and, when
    measured, its linear floor and the ratio of the Newton solve to it; t_output grows when
    results.write records the level."""
    columns = dict(phases.columns(comm), peak_memory_mb=timing.peak_memory_mb(comm),
                   peak_memory_mesh_mb=mesh_peak_mb)
    if outcome.floor_s is not None:
        columns.update(t_linear_floor=outcome.floor_s, floor_ratio=columns["t_newton"] / outcome.floor_s)
    return columns


def tables(cfg, levels):
    """The record's tables, the main one first: rates, work_precision and the Γ_C pressure of each level."""
    rows = rate_table(levels)
    pressure = [row for lv in levels for row in lv.profile]
    named = {"rates": rows, "pressure": pressure} if pressure else {"rates": rows}
    return dict(named, work_precision=work_precision_rows(rows))


def summary(cfg, levels):
    """The verdict against the proven rates of the study's method (summary.csv)."""
    return verdict.summarize(cfg, levels, registry.expected)


def levels_of(levels):
    """The Levels recorded one group each in study.h5."""
    return levels


def parts(cfg, levels):
    """Studies of their own inside this one: none."""
    return []


def reported(cfg, named):
    """The rate table and its convergence figures; the contact pressure along Γ_C, level by level."""
    figures = [Figure("convergence", "convergence", named["rates"])]
    if named.get("pressure"):
        figures.append(Figure("pressure", "pressure", (named["pressure"], named["rates"])))
    return [Table("rates", named["rates"], paper=True)], figures


def compared(named):
    """What `compare` overlays: the rate table."""
    return {"": named["rates"]}


def title(cfg, name):
    """A one-line plot title: dimension and the method's parameters (α and the ε law of the penalty)."""
    return f"{name}: d = {cfg.dimension}, {registry.method_of(cfg).parameters(cfg)}"
