"""ε-sweeps: the model error ||u_{ε,h} − u_{S,h}|| on fixed meshes (paper Lemma 2.5); the sweep, fitted and
reference tables and the model-error figure."""
import dataclasses
import time
from dataclasses import dataclass

from mpi4py import MPI
from dolfinx import fem

from ..analysis import rates
from ..meshing import meshes
from ..problems import measure
from ..problems.registry import problem_of
from ..solve import solver, strategies
from .level import Figure, Table, rate_table
from .signorini import signorini_level

NAME = "epsilon_sweep"
UNIT = "solves"
RESUMABLE = False
POINTS = False  # a study of its own levels or solves (a map: points, run and recorded by app/maps)
MODEL_ERRORS = ("L2", "H1", "L2_gamma_c", "penetration")  # of u_{ε,h} − u_{S,h} (measure.model_differences)
SWEEP_COLUMNS = ("N", "h", "dofs", "alpha", "epsilon", "converged", "newton_its",
                 "L2", "rate_L2", "H1", "rate_H1", "L2_gamma_c", "rate_L2_gamma_c",
                 "penetration", "rate_penetration", "time_s", "reason")


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


def run(cfg, on_level=None, comm=MPI.COMM_WORLD, monitor=None, done=()):
    """For every mesh: the VI's u_{S,h}, then for every α the compliance u_{ε,h} down the ε list (the data
    checked once per mesh, by signorini_level, before the first solve: both share u_S, f and g)."""
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
    ds_c = domain.ds_c(measure.product_degree(V))
    solved = cfg.limit.epsilon[0]
    with strategies.newton_for(cfg.solver, problem) as newton:
        for value in cfg.limit.epsilon:
            start = time.perf_counter()
            outcome = strategies.descend(newton, problem, value, cfg.solver, solved)
            solved = value if outcome.converged else solved
            found = problem_of(cfg, limit=True).model_differences(cfg, domain, u_h, u_S, ds_c)
            elapsed = domain.mesh.comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
            yield Point(domain.n, domain.h, solver.global_dofs(V), alpha, value, outcome, found, elapsed)


def tables(cfg, sweep):
    """sweep, fitted and reference (none before the first solve, when the result is still the empty
    list the study starts from)."""
    if isinstance(sweep, list):
        return {}
    return {"sweep": sweep_table(sweep), "fitted": fitted_table(sweep, cfg.limit.fit_last),
            "reference": rate_table(sweep.references)}


def summary(cfg, sweep):
    """No verdict: the paper proves no rate in ε for the discrete model error."""
    return None


def compared(named):
    """What `compare` overlays: the Signorini solutions' rate table on the sweep's meshes."""
    return {"reference": named.get("reference", [])}


def levels_of(sweep):
    """No level groups: the tables hold every solve."""
    return []


def parts(cfg, sweep):
    return []


def reported(cfg, named):
    """Its three tables, and the model error against ε on the finest mesh."""
    shown = [Table("sweep", named["sweep"], terminal=False), Table("fitted", named["fitted"]),
             Table("reference", named["reference"], paper=True)]
    finest = max((row["N"] for row in named["sweep"]), default=None)
    rows = [row for row in named["sweep"] if row["N"] == finest]
    return shown, [Figure("model_error", "model_error", rows)] if rows else []


def title(cfg, name):
    return f"{name}: d = {cfg.dimension}, model error against ε"


def sweep_table(sweep):
    """One row per (mesh, α, ε): the differences and their rates in ε against the previous ε."""
    rows = []
    for group in _sweep_groups(sweep.points):
        eps = [p.eps for p in group]
        ok = [p.outcome.converged for p in group]
        observed = {m: rates.observed(eps, [p.differences[m] for p in group], ok) for m in MODEL_ERRORS}
        for k, p in enumerate(group):
            row = {"N": p.n, "h": p.h, "dofs": p.dofs, "alpha": p.alpha, "epsilon": p.eps,
                   "converged": p.outcome.converged, "newton_its": p.outcome.newton_its}
            for m in MODEL_ERRORS:
                row[m] = p.differences[m] if ok[k] else None
                row[f"rate_{m}"] = observed[m][k]
            row.update(time_s=p.time_s, reason=p.outcome.reason)
            rows.append(row)
    return rows


def fitted_table(sweep, last):
    """One row per (mesh, α): the least-squares slope of log(difference) against log ε over the
    `last` smallest converged ε, for every measure."""
    rows = []
    for group in _sweep_groups(sweep.points):
        eps, ok = [p.eps for p in group], [p.outcome.converged for p in group]
        used = [p for p in group if p.outcome.converged][-last:]
        row = {"N": group[0].n, "h": group[0].h, "alpha": group[0].alpha, "points": len(used),
               "eps_max": used[0].eps if used else None, "eps_min": used[-1].eps if used else None}
        for m in MODEL_ERRORS:
            row[f"fit_{m}"] = rates.fitted(eps, [p.differences[m] for p in group], ok, last)
        rows.append(row)
    return rows


def _sweep_groups(points):
    """The points split into runs of one (mesh, α), in solve order."""
    groups = {}
    for p in points:
        groups.setdefault((p.n, p.alpha), []).append(p)
    return list(groups.values())
