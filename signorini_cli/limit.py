"""The Signorini limit (paper Lemma 2.5, docs/limit.md): the model error ||u_{ε,h} − u_{S,h}|| of ε-sweeps
on fixed meshes, and total-error studies ||u_S − u_h^{ε(h)}|| with ε = θ h^p beside the VI solved directly."""
import dataclasses
import time
from dataclasses import dataclass

import numpy as np
import ufl
from mpi4py import MPI

from dolfinx import fem

from . import config, files, measure, meshes, model, rates, solver, vi

MEASURES = ("L2", "H1", "L2_gamma_c", "penetration")  # of u_{ε,h} − u_{S,h}; penetration: max_Γc [u_{ε,h}]_+
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


@dataclass
class Total:
    """A total-error study: sub-study name -> (config, levels); iterating gives every level."""
    studies: dict

    def __iter__(self):
        return (level for _, levels in self.studies.values() for level in levels)


def run_study(cfg, on_level=None, comm=MPI.COMM_WORLD, monitor=None):
    """Dispatch on study_type; on_level(done_so_far) after every solve, as in study.run_study;
    the Newton `monitor` (progress) follows the levels of a signorini study only."""
    if cfg.study_type == "signorini":
        return run_signorini(cfg, on_level, comm, monitor)
    run = {"epsilon_sweep": run_sweep, "total_error": run_total}
    return run[cfg.study_type](cfg, on_level, comm)


def run_signorini(cfg, on_level=None, comm=MPI.COMM_WORLD, monitor=None):
    """The VI refinement study: one Level per mesh, the SPEC rate table with ε = 0."""
    levels = []
    for index, n in enumerate(cfg.mesh.refinements):
        levels.append(vi.solve_level(cfg, index, n, comm, monitor))
        if on_level is not None:
            on_level(levels)
        if not levels[-1].outcome.converged and cfg.solver.on_failure == "stop":
            break
    return levels


def run_sweep(cfg, on_level=None, comm=MPI.COMM_WORLD):
    """For every mesh: the VI's u_{S,h}, then for every α the compliance u_{ε,h} down the ε list."""
    sweep = Sweep([], [])
    for index, n in enumerate(cfg.mesh.refinements):
        start = time.perf_counter()
        domain = meshes.build(cfg.mesh, cfg.contact, n, comm)
        reference, u_S = vi.reference(cfg, index, domain, start)
        sweep.references.append(reference)
        for alpha in cfg.limit.alpha:
            for point in sweep_alpha(cfg, domain, u_S, alpha):
                sweep.points.append(point)
                if on_level is not None:
                    on_level(sweep)
    return sweep


def sweep_alpha(cfg, domain, u_S, alpha):
    """Compliance solutions for decreasing ε, each started from the last converged one (continuation)."""
    from .study import dirichlet_condition
    V = u_S.function_space
    eps = fem.Constant(domain.mesh, cfg.limit.epsilon[0])
    u_h = fem.Function(V, name="u_eps_h")
    forms_ = model.forms(dataclasses.replace(cfg, alpha=alpha), domain, u_h, eps)
    bc = dirichlet_condition(V, domain, forms_.u_exact)
    dofs = solver.global_dofs(V)
    newton = solver.NewtonSolver(forms_.F, forms_.J, u_h, [bc],
                                 solver.petsc_options(cfg.solver, cfg.dimension, dofs=dofs),
                                 test=solver.success_test(cfg.solver), contact=forms_.contact)
    try:
        for value in cfg.limit.epsilon:
            start = time.perf_counter()
            eps.value = value
            last_good = u_h.x.array.copy()
            outcome = newton.solve()
            found = differences(u_h, u_S, forms_.ds_c, vi.contact_dofs(V, domain))
            if not outcome.converged:
                u_h.x.array[:] = last_good
            elapsed = domain.mesh.comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
            yield Point(domain.n, domain.h, dofs, alpha, value, outcome, found, elapsed)
    finally:
        newton.destroy()


def differences(u_eps, u_S, ds_c, gamma_c_dofs):
    """||u_{ε,h} − u_{S,h}|| in L2(Ω), H1 (seminorm), L2(Γ_C), and the largest penetration max_Γc [u_{ε,h}]_+
    (a nodal max: u_{ε,h} is P1). Both are P1 on one mesh, so the default quadrature is exact."""
    msh = u_eps.function_space.mesh
    e = u_eps - u_S
    dx = ufl.dx(domain=msh)
    local_max = float(np.max(u_eps.x.array[gamma_c_dofs], initial=0.0))
    return {"L2": np.sqrt(abs(measure.integrate(e**2, dx))),
            "H1": np.sqrt(abs(measure.integrate(ufl.inner(ufl.grad(e), ufl.grad(e)), dx))),
            "L2_gamma_c": np.sqrt(abs(measure.integrate(e**2, ds_c))),
            "penetration": msh.comm.allreduce(local_max, op=MPI.MAX)}


def run_total(cfg, on_level=None, comm=MPI.COMM_WORLD):
    """A refinement study with ε = θ h^p for every α and p, and the same study by the VI, side by side."""
    from . import study
    total = Total({})
    for name, sub in sub_studies(cfg):
        levels = []
        total.studies[name] = (sub, levels)

        def record(done, levels=levels):
            levels[:] = done
            if on_level is not None:
                on_level(total)

        study.run_study(sub, on_level=record, comm=comm)
    return total


def sub_studies(cfg):
    """(name, config) of every sub-study of a total-error study: alpha<α>-p<p> and signorini (the VI)."""
    subs = []
    for alpha in cfg.limit.alpha:
        for p in cfg.limit.exponent:
            name = f"alpha{alpha:g}-p{p:g}"
            epsilon = config.Epsilon("power", cfg.limit.theta, p)
            subs.append((name, _sub_study(cfg, name, "refinement", alpha=alpha, epsilon=epsilon)))
    subs.append(("signorini", _sub_study(cfg, "signorini", "signorini")))
    return subs


def _sub_study(cfg, name, study_type, **changes):
    """A plain study of its own type, written to <output>/<study>/<name>/."""
    output = dataclasses.replace(cfg.output, dir=str(cfg.output_dir))
    return dataclasses.replace(cfg, study=name, study_type=study_type, limit=None, output=output, **changes)


# --- tables ----------------------------------------------------------------------------------------

def sweep_table(sweep):
    """One row per (mesh, α, ε): the differences and their rates in ε against the previous ε."""
    rows = []
    for group in _groups(sweep.points):
        eps = [p.eps for p in group]
        ok = [p.outcome.converged for p in group]
        observed = {m: rates.observed(eps, [p.differences[m] for p in group], ok) for m in MEASURES}
        for k, p in enumerate(group):
            row = {"N": p.n, "h": p.h, "dofs": p.dofs, "alpha": p.alpha, "epsilon": p.eps,
                   "converged": p.outcome.converged, "newton_its": p.outcome.newton_its}
            for m in MEASURES:
                row[m] = p.differences[m] if ok[k] else None
                row[f"rate_{m}"] = observed[m][k]
            row.update(time_s=p.time_s, reason=p.outcome.reason)
            rows.append(row)
    return rows


def fitted_table(sweep, last):
    """One row per (mesh, α): the least-squares slope of log(difference) against log ε over the
    `last` smallest converged ε, for every measure."""
    rows = []
    for group in _groups(sweep.points):
        eps, ok = [p.eps for p in group], [p.outcome.converged for p in group]
        used = [p for p in group if p.outcome.converged][-last:]
        row = {"N": group[0].n, "h": group[0].h, "alpha": group[0].alpha, "points": len(used),
               "eps_max": used[0].eps if used else None, "eps_min": used[-1].eps if used else None}
        for m in MEASURES:
            row[f"fit_{m}"] = rates.fitted(eps, [p.differences[m] for p in group], ok, last)
        rows.append(row)
    return rows


def total_table(total, last):
    """One row per sub-study: its finest level's errors against u_S, the last and the fitted rates."""
    from . import results
    rows = []
    for name, (sub, levels) in total.studies.items():
        table = results.table(levels) if levels else []
        finest = table[-1] if table else {}
        vi_study = sub.study_type == "signorini"
        row = {"study": name, "solver": "signorini" if vi_study else "compliance",
               "alpha": None if vi_study else sub.alpha, "p": None if vi_study else sub.epsilon.exponent,
               "levels": len(levels), "N": finest.get("N"), "h": finest.get("h"), "epsilon": finest.get("epsilon"),
               "converged": all(lv.outcome.converged for lv in levels)}
        for norm in ("L2", "H1"):
            row[norm] = finest.get(norm)
            row[f"rate_{norm}"] = finest.get(f"rate_{norm}")
            row[f"fit_{norm}"] = rates.fitted([lv.h for lv in levels], [lv.errors.get(norm) for lv in levels],
                                              [lv.outcome.converged for lv in levels], last)
        rows.append(row)
    return rows


def _groups(points):
    """The points split into runs of one (mesh, α), in solve order."""
    groups = {}
    for p in points:
        groups.setdefault((p.n, p.alpha), []).append(p)
    return list(groups.values())


# --- output ----------------------------------------------------------------------------------------

def tables(cfg, result):
    """The CSV tables of a study: name -> rows."""
    from . import results
    if cfg.study_type == "epsilon_sweep":
        return {"sweep": sweep_table(result), "fitted": fitted_table(result, cfg.limit.fit_last),
                "reference": results.table(result.references)}
    return {"total": total_table(result, cfg.limit.fit_last)}


def write(cfg, result, comm=MPI.COMM_WORLD):
    """Write the study's CSV tables and study.h5 (atomically, rank 0; every rank waits); a total-error
    study also writes each sub-study's SPEC rate table in its own folder."""
    from . import results
    if cfg.study_type == "total_error":
        for sub, levels in result.studies.values():
            if levels:
                results.write(sub, levels, comm)
    named = tables(cfg, result)
    if comm.rank == 0:
        folder = cfg.output_dir
        folder.mkdir(parents=True, exist_ok=True)
        for name, rows in named.items():
            files.replace(folder / f"{name}.csv", lambda path, rows=rows: path.write_text(results.csv_text(rows)))
        files.replace(folder / "study.h5", lambda path: _write_h5(path, cfg, named, comm.size))
    comm.barrier()
    return named


def _write_h5(path, cfg, named, mpi_size):
    import h5py
    import yaml
    from . import results
    with h5py.File(path, "w") as h5:
        h5.attrs["config"] = cfg.text
        h5.attrs["config_resolved"] = yaml.safe_dump(config.to_dict(cfg), sort_keys=False)
        if results.git_revision():
            h5.attrs["git_revision"] = results.git_revision()
        h5.attrs["study"] = cfg.study
        h5.attrs["study_type"] = cfg.study_type
        h5.attrs["mpi_size"] = mpi_size
        for name, version in results.versions().items():
            h5.attrs[f"version_{name}"] = version
        for name, rows in named.items():
            results._write_table(h5.create_group(name), rows)


def run(cfg, comm=MPI.COMM_WORLD, quiet=False):
    """The command line's run of an ε-sweep or total-error study: solve, write after every solve, then
    (rank 0) the report files and, unless quiet, the summary; True when every solve converged."""
    result = run_study(cfg, on_level=lambda done: write(cfg, done, comm), comm=comm)
    named = tables(cfg, result)
    if comm.rank == 0:
        written = report_files(cfg, result, named)
        if not quiet:
            print(f"study {cfg.study} ({cfg.study_type}): {cfg.output_dir}")
            for name in ("reference", "fitted", "total"):
                if name in named:
                    print(f"\n{name}:\n{format_rows(named[name])}")
            names = [str(path.relative_to(cfg.output_dir)) for path in written]
            print("wrote " + (", ".join(names) if len(names) <= 4 else f"{len(names)} tables and figures "
                              "(rates.md, rates.tex, plots) in the sub-study folders"))
    return comm.allreduce(all(solve.outcome.converged for solve in result), op=MPI.LAND)


def report_files(cfg, result, named):
    """What `run` leaves besides the tables: each total-error sub-study's rates.md/.tex (and plots),
    the sweep's model-error plot; plots only with output.plots."""
    from . import report, results
    written = []
    if cfg.study_type == "total_error":
        for sub, levels in result.studies.values():
            if levels:
                study = report.Study(sub.study, sub.output_dir, results.table(levels))
                written += report.write(study, sub, sub.output.digits, plots=sub.output.plots)
    elif cfg.output.plots and named["sweep"]:
        from .limit_docs import plot_model_error  # matplotlib only when plots are asked for
        finest = max(row["N"] for row in named["sweep"])
        for suffix in (".png", ".pdf"):
            written.append(plot_model_error([row for row in named["sweep"] if row["N"] == finest],
                                            cfg.output_dir / f"model_error{suffix}"))
    return written


def format_rows(rows):
    """A right-aligned text table: floats .3e, rates and fitted slopes .2f, '-' for missing values."""
    if not rows:
        return "(nothing solved)"
    columns = list(rows[0])
    cells = [[_format(c, row[c]) for c in columns] for row in rows]
    widths = [max(len(c), *(len(line[i]) for line in cells)) for i, c in enumerate(columns)]
    lines = ["  ".join(c.rjust(w) for c, w in zip(columns, widths))]
    lines += ["  ".join(cell.rjust(w) for cell, w in zip(line, widths)) for line in cells]
    return "\n".join(lines)


def _format(column, value):
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "NO"
    if column.startswith(("rate_", "fit_")) or column in ("alpha", "p", "time_s"):
        return f"{value:.2f}" if column != "alpha" and column != "p" else f"{value:g}"
    if isinstance(value, float):
        return f"{value:.3e}"
    return str(value)
