"""docs/limit.md from the runs of configs/limit/ (`make limit`): tables and the model-error plot.

    python scripts/limit_page.py CONFIG.yaml ... [--output RESULTS] [--out docs/limit.md]
reads each config's results (study_type signorini, epsilon_sweep, total_error) and writes the page
and its figure next to it; every number on the page comes from those results."""
import argparse
import sys
from pathlib import Path


import cells
import provenance
from signorini_cli import config
from signorini_cli.analysis import rates
from signorini_cli.record import csvfile, h5
from signorini_cli.report import plots

PLOT = "limit-model-error.png"


def main(argv=None):
    parser = argparse.ArgumentParser(prog="scripts/limit_page.py", description=__doc__.split("\n")[0])
    parser.add_argument("configs", nargs="+", help="the configs/limit studies, already run")
    parser.add_argument("--output", help="the results folder the studies were run with (overrides output.dir)")
    parser.add_argument("--out", default="docs/limit.md", help="the page to write; the plot goes next to it")
    args = parser.parse_args(argv)
    studies = {}
    for path in args.configs:
        cfg = config.load(path, [f"output.dir={args.output}"] if args.output else [])
        studies[cfg.study_type] = (path, cfg)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    made_from = provenance.line("limit", [cfg.output_dir for _, cfg in studies.values()])
    sections = [HEADER.replace("{provenance}", made_from)]
    if "signorini" in studies:
        sections.append(signorini_section(*studies["signorini"]))
    if "epsilon_sweep" in studies:
        sections.append(sweep_section(*studies["epsilon_sweep"], out.parent))
    if "total_error" in studies:
        sections.append(total_section(*studies["total_error"]))
    sections.append(versions_section(studies.values()))
    out.write_text("\n\n".join(sections) + "\n")
    print(f"wrote {out}")
    return 0


HEADER = """# The Signorini limit: the VI solved directly, and the model error of the compliance model

{provenance} Runs of `configs/limit/*.yaml`.
The Signorini problem, its manufactured solution u_S and why the heuristic rates below hold are
derived in [signorini-solution.md](signorini-solution.md). Norms: `L2` = ‖·‖_{L²(Ω)}, `H1` = |·|_{H¹(Ω)}
(seminorm), `L2_gamma_c` = ‖·‖_{L²(Γ_C)}, `penetration` = max_{Γ_C} [u_{ε,h}]_+."""


def signorini_section(path, cfg):
    rows = csvfile.read(cfg.output_dir / "rates.csv")
    h = [r["h"] for r in rows]
    pressure_rates = rates.observed(h, [r["pressure_L2"] for r in rows], [r["converged"] for r in rows])
    for row, rate in zip(rows, pressure_rates):
        row["rate_pressure_L2"] = rate
    columns = ("N", "h", "dofs", "newton_its", "L2", "rate_L2", "H1", "rate_H1", "contact_nodes",
               "contact_measure", "contact_force", "pressure_L2", "rate_pressure_L2")
    last = rows[-1]
    return "\n".join([
        "## 1. The discrete Signorini problem, solved as a variational inequality",
        "",
        f"`{path}`: u_h ≤ 0 at the Γ_C nodes, PETSc SNES `vinewtonrsls` with bounds (upper 0 on Γ_C, "
        "+∞ elsewhere, Dirichlet dofs pinned), on the manufactured u_S (contact set x ≤ 1/2 of measure 1/2). "
        "`contact_measure` is the lumped measure Σ ∫_Γc φ_i over the Γ_C nodes at the bound; the discrete "
        "contact pressure is the residual λ_i = −F(u_h)_i at the Γ_C nodes divided by ∫_Γc φ_i, compared with "
        "−∂_n u_S at the nodes in the lumped `pressure_L2`; `contact_force` = Σ λ_i over the Γ_C nodes off Γ_D.",
        "",
        markdown(rows, columns),
        "",
        f"Finest level N = {last['N']}: H1 rate {cells.rate(last['rate_H1'])}, L2 rate {cells.rate(last['rate_L2'])}, "
        f"all levels converged: {cells.yes(all(r['converged'] for r in rows))}.",
    ])


def sweep_section(path, cfg, folder):
    sweep = csvfile.read(cfg.output_dir / "sweep.csv")
    fitted = csvfile.read(cfg.output_dir / "fitted.csv")
    reference = {r["N"]: r for r in csvfile.read(cfg.output_dir / "reference.csv")}
    finest = max(r["N"] for r in sweep)
    plots.model_error([r for r in sweep if r["N"] == finest], folder / PLOT)
    for row in fitted:
        row["1/alpha"] = 1.0 / row["alpha"]
    lines = [
        "## 2. The model error ‖u_{ε,h} − u_{S,h}‖ as ε → 0",
        "",
        f"`{path}`: on each mesh the compliance solutions u_{{ε,h}} (data f, u_D of u_S, contact data g = 0), "
        "ε decreasing, each solve started from the previous one, against the discrete Signorini solution "
        "u_{S,h} on the same mesh (section 1's solver). Both live in the same P1 space, so this is the pure "
        "model error of the compliance model, free of discretisation error.",
        "",
        f"![model error against ε, N = {finest}]({PLOT})",
        "",
        f"Decreasing at every step for every α, mesh and measure: {cells.yes(monotone(sweep))}. "
        f"Fitted rates in ε (least squares over the {cfg.limit.fit_last} smallest ε), beside 1/α:",
        "",
        markdown(fitted, ("N", "alpha", "eps_max", "eps_min", "fit_L2", "fit_H1", "fit_L2_gamma_c",
                          "fit_penetration", "1/alpha")),
        "",
        alpha_finding(fitted),
        "",
        crossover_paragraph(sweep, reference),
        "",
        f"The whole sweep on N = {finest} (rates against the previous ε):",
        "",
        markdown([r for r in sweep if r["N"] == finest],
                 ("alpha", "epsilon", "newton_its", "L2", "rate_L2", "H1", "rate_H1", "L2_gamma_c",
                  "rate_L2_gamma_c", "penetration", "rate_penetration")),
    ]
    return "\n".join(lines)


def alpha_finding(fitted, tolerance=0.05):
    """How the fitted H1 rate depends on α on the finest mesh, against 1/α."""
    finest = max(r["N"] for r in fitted)
    rows = [r for r in fitted if r["N"] == finest]
    pairs = ", ".join(f"α = {r['alpha']:g}: {cells.rate(r['fit_H1'])} (1/α = {1 / r['alpha']:.2f})" for r in rows)
    gap = max(abs(r["fit_H1"] - 1 / r["alpha"]) for r in rows if r["fit_H1"] is not None)
    verdict = (f"within {tolerance} of 1/α for every α" if gap <= tolerance
               else f"up to {gap:.2f} away from 1/α")
    return (f"**How the rate depends on α**: on N = {finest} the fitted H1 rates are {pairs}: {verdict}. "
            "The heuristic behind 1/α: on the contact set the penetration solves [u_ε]_+^α ≈ ε·(−∂_n u_S), so "
            "the model error is O(ε^{1/α}); a smoother law (larger α) converges more slowly in ε, and its "
            "asymptotic range starts at smaller ε.")


def crossover_paragraph(sweep, reference):
    return "\n".join([
        "Largest ε of the sweep at which the model error ‖u_{ε,h} − u_{S,h}‖ is already below the "
        "discretisation error ‖u_S − u_{S,h}‖ of the VI on the same mesh (`≥`: the whole sweep is below, "
        "`<`: not even the smallest ε is): for smaller ε the discretisation dominates the total error.",
        "",
        markdown(crossover(sweep, reference), ("N", "alpha", "L2", "H1"))])


def crossover(sweep, reference):
    """Per mesh and α, the largest swept ε whose model error is below the VI's discretisation error."""
    rows = []
    for n, ref in sorted(reference.items()):
        for alpha in sorted({r["alpha"] for r in sweep}):
            curve = [r for r in sweep if r["N"] == n and r["alpha"] == alpha]
            row = {"N": n, "alpha": alpha}
            for norm in ("L2", "H1"):
                if ref.get(norm) is None:  # a data-only scene has no discretisation error to compare with
                    continue
                below = [r["epsilon"] for r in curve if r[norm] is not None and r[norm] < ref[norm]]
                if not below:  # still above at the smallest swept ε
                    row[norm] = f"< {min(r['epsilon'] for r in curve):.0e}"
                else:
                    row[norm] = ("≥ " if len(below) == len(curve) else "") + f"{max(below):.0e}"
            rows.append(row)
    return rows


def total_section(path, cfg):
    rows = csvfile.read(cfg.output_dir / "total.csv")
    for row in rows:
        if row["solver"] == "compliance":
            row["expected_H1"] = min(1.0, row["p"] / row["alpha"])
            row["expected_L2"] = min(2.0, row["p"] / row["alpha"])
    columns = ("study", "alpha", "p", "N", "epsilon", "L2", "rate_L2", "fit_L2", "expected_L2",
               "H1", "rate_H1", "fit_H1", "expected_H1")
    return "\n".join([
        "## 3. The total error ‖u_S − u_h^{ε(h)}‖ with ε = θ h^p, beside the VI",
        "",
        f"`{path}`: refinement studies N = {', '.join(map(str, cfg.mesh.refinements))} of the compliance model "
        f"with ε = {cfg.limit.theta:g}·h^p, measured against the exact Signorini solution u_S, and the same "
        "refinement study solved by the VI directly (row `signorini`, ε = 0). `rate_*` is the rate of the "
        f"last two levels, `fit_*` the least-squares slope of the last {cfg.limit.fit_last}; `expected_*` is the "
        "heuristic min(1, p/α) in H1 and min(2, p/α) in L2 from ‖u_S − u_{ε,h}‖ ≤ ‖u_S − u_{S,h}‖ + "
        "‖u_{S,h} − u_{ε,h}‖ = O(h^{1 or 2}) + O(ε^{1/α}) (section 2), not a theorem. Each study's rate "
        "table is in its own folder (`<output>/" + cfg.study + "/<study>/rates.csv`).",
        "",
        markdown(rows, columns),
        "",
        "The paper's rates bound u_ε − u_{ε,h} for ε ≳ h; against the Signorini solution the "
        "model error adds O(ε^{1/α}), so by the heuristic ε = θh keeps O(h) in H1 only for α = 1, and the VI's "
        "own rates need ε ≲ h^α (H1) and ε ≲ h^{2α} (L2). The expected values are asymptotic: where ε(h) is "
        "still in the pre-asymptotic range of section 2 (local ε-rates below 1/α, larger α and p = 1), the "
        "observed rates fall short of them.",
    ])


def versions_section(studies):
    lines = ["## Provenance", ""]
    for path, cfg in studies:
        attrs = h5.read(cfg.output_dir / "study.h5").attrs
        versions = ", ".join(f"{k[len('version_'):]} {attrs[k]}" for k in sorted(attrs) if k.startswith("version_"))
        lines.append(f"- `{path}` → `{cfg.output_dir}`: MPI size {attrs['mpi_size']}; {versions}")
    return "\n".join(lines)


def monotone(rows):
    """Every measure strictly decreases along ε within each (mesh, α)."""
    groups = {}
    for r in rows:
        groups.setdefault((r["N"], r["alpha"]), []).append(r)
    measures = ("L2", "H1", "L2_gamma_c", "penetration")
    return all(b[m] < a[m] for group in groups.values() for a, b in zip(group, group[1:]) for m in measures)


def markdown(rows, columns):
    """A Markdown table: errors .3e, rates .2f, '–' where undefined."""
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    for row in rows:
        lines.append("| " + " | ".join(_cell(c, row.get(c)) for c in columns) + " |")
    return "\n".join(lines)


def _cell(column, value):
    if value is None:
        return "–"
    if isinstance(value, bool):
        return cells.yes(value)
    if column.startswith(("rate_", "fit_", "expected_")) or column == "1/alpha":
        return f"{value:.2f}"
    if column in ("alpha", "p"):
        return f"{value:g}"
    if isinstance(value, float):
        return f"{value:.3e}"
    return str(value)


if __name__ == "__main__":
    sys.exit(main())
