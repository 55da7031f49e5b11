"""docs/elements.md from the runs of configs/elements/ (`make elements`): P2 against P1 on one scalar problem
and one elastic problem.

    python scripts/elements_page.py CONFIG.yaml ... [--output RESULTS] [--out docs/elements.md]
reads each config's results and writes the page; every number on it comes from those results."""
import argparse
import sys
from pathlib import Path

import cells
import provenance
from signorini_cli import config
from signorini_cli.analysis import rates
from signorini_cli.record import results

COLUMNS = ("N", "h", "dofs", "newton_its", "L2", "rate_L2", "H1", "rate_H1", "pos_gc", "rate_pos_gc",
           "contact_quadrature")
NORMS = ("L2", "H1", "pos_gc")
P2_RULE = "exact"  # the default contact rule of element.degree 2
SCALAR, ELASTIC = "poisson", "elasticity"  # the problems compared (problem.pde)


def main(argv=None):
    parser = argparse.ArgumentParser(prog="scripts/elements_page.py", description=__doc__.split("\n")[0])
    parser.add_argument("configs", nargs="+", help="the configs/elements studies, already run")
    parser.add_argument("--output", help="the results folder the studies were run with (overrides output.dir)")
    parser.add_argument("--out", default="docs/elements.md", help="the page to write")
    args = parser.parse_args(argv)
    runs = [(path, config.load(path, [f"output.dir={args.output}"] if args.output else [])) for path in args.configs]
    studies = {(cfg.problem.pde, cfg.dimension, cfg.element.degree, cfg.problem.exact_solves,
                str(cfg.contact_quadrature)): (path, cfg, results.load(cfg.output_dir).rows) for path, cfg in runs}
    scalar = {key[2:]: study for key, study in studies.items() if key[:2] == (SCALAR, 2)}
    p1, p2 = scalar[(1, "compliance", "exact")], scalar[(2, "compliance", str(P2_RULE))]
    checks = [v for (degree, solves, rule), v in scalar.items()
              if degree == 2 and solves == "compliance" and rule != str(P2_RULE)]
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    sections = [HEADER.replace("{provenance}", provenance.line("elements", [cfg.output_dir for _, cfg in runs])),
                study_section("P1", *p1), study_section("P2", *p2), comparison(p1, p2)]
    sections += [quadrature_section(p2, check) for check in checks]
    limit = [scalar.get((k, "signorini", rule)) for k, rule in ((1, "exact"), (2, str(P2_RULE)))]
    if all(limit):
        sections.append(signorini_section(*limit, p1, p2))
    for dim in (2, 3):
        elastic = [studies.get((ELASTIC, dim, k, "compliance", rule)) for k, rule in ((1, "exact"), (2, str(P2_RULE)))]
        if all(elastic):
            sections.append(elastic_section(*elastic))
    out.write_text("\n\n".join(sections) + "\n")
    print(f"wrote {out}")
    return 0


HEADER = """# P2 elements for the compliance model

{provenance} Runs of `configs/elements/*.yaml`.
The same problem, 2-D, α = 2, ε = h, u_ex = sin(2πx)(1−y)², contact on the bottom face, solved with P1 and
with P2 Lagrange (`element: {degree: 2}`). The paper's estimates (Cor. 3.2, Lemma 4.2) are for P1; for P2
nothing is proven, so the P2 rates below are measurements, and the verdicts of a P2 study say `not covered`.
The P2 contact term (1/ε)∫_Γc [u_h]_+^α v and the data term (1/ε)∫_Γc [u_ex]_+^α v are integrated exactly
(column `contact_quadrature`): each Γ_C facet cut at the zeros of the quadratic trace (closed form) and of
u_ex, a tanh-sinh rule on each smooth piece, converged to round-off. Norms: `L2` = ‖u − u_h‖_{L²(Ω)},
`H1` = |u − u_h|_{H¹(Ω)}, `pos_gc` = ‖[u]_+ − [u_h]_+‖_{L³(Γ_C)} (α + 1 = 3)."""


def study_section(label, path, cfg, rows):
    fits = {norm: fit(rows, norm) for norm in NORMS}
    return "\n".join([
        f"## {label}: `{path}`",
        "",
        markdown(rows, COLUMNS),
        "",
        f"Fitted over the last {rates.FIT_LEVELS} levels: " + ", ".join(f"{n} {cells.rate(fits[n])}" for n in NORMS)
        + f"; all levels converged: {cells.yes(all(r['converged'] for r in rows))}.",
    ])


def comparison(p1, p2):
    """What the rates show, in numbers: the fitted orders against the interpolation orders k + 1 (L2) and
    k (H1) of degree k, and the finest levels' errors side by side."""
    (_, _, rows1), (_, _, rows2) = p1, p2
    fit1, fit2 = ({norm: fit(rows, norm) for norm in NORMS} for rows in (rows1, rows2))
    last1, last2 = rows1[-1], rows2[-1]
    lines = ["## What the rates show", ""] + rate_lines(fit1, fit2)
    lines.append(f"- At N = {last2['N']}: P2 L2 {last2['L2']:.3e} and H1 {last2['H1']:.3e} with {last2['dofs']:,} "
                 f"dofs against P1 L2 {last1['L2']:.3e} and H1 {last1['H1']:.3e} with {last1['dofs']:,} dofs.")
    lines += equal_dofs_lines(rows1, rows2)
    lines.append("- The manufactured data g = ε∂_n u_ex + [u_ex]_+^α make u_ex the exact solution of the "
                 "compliance problem at each level's ε, so these are discretisation errors of that problem; "
                 "its distance to the Signorini solution, the model error, is not in them (the last section).")
    return "\n".join(lines)


def rate_lines(fit1, fit2):
    """The fitted orders of P1 and P2 against the interpolation orders k + 1 (L2) and k (H1) of degree k."""
    lines = []
    for label, fits, k in (("P1", fit1, 1), ("P2", fit2, 2)):
        lines.append(f"- {label}: L2 {cells.rate(fits['L2'])} and H1 {cells.rate(fits['H1'])} against the "
                     f"interpolation orders {k + 1} and {k} of degree {k}: the penalty term (weight 1/ε = 1/h) "
                     + ("keeps" if keeps(fits, k) else "does not keep") + " the best order the element allows"
                     + (f" ({keeps_detail(fits, k)})." if not keeps(fits, k) else "."))
    lines.append(f"- Γ_C: pos_gc {cells.rate(fit1['pos_gc'])} (P1) and {cells.rate(fit2['pos_gc'])} (P2).")
    return lines


def equal_dofs_lines(rows1, rows2):
    """P1 against P2 on the levels with the same number of dofs."""
    lines = []
    for r2 in rows2:
        r1 = next((r for r in rows1 if r["dofs"] == r2["dofs"]), None)
        if r1 is not None:
            lines.append(f"- At equal dofs ({r2['dofs']:,}: P2 at N = {r2['N']}, P1 at N = {r1['N']}): P2's L2 "
                         f"error is {r1['L2'] / r2['L2']:.0f} times smaller than P1's, its H1 error "
                         f"{r1['H1'] / r2['H1']:.0f} times.")
    return lines


def elastic_section(p1, p2):
    """The elastic problem with P1 and P2: both tables, their fitted rates and the finest levels side by side."""
    (path1, cfg, rows1), (path2, _, rows2) = p1, p2
    fit1, fit2 = ({norm: fit(rows, norm) for norm in NORMS} for rows in (rows1, rows2))
    last1, last2 = rows1[-1], rows2[-1]
    return "\n".join([
        f"## Linear elasticity, {cfg.dimension}-D: P2 against P1",
        "",
        f"`{path1}` and `{path2}`: linear elasticity with normal compliance ([elasticity.md](elasticity.md)), "
        + ("plane strain, " if cfg.dimension == 2 else "")
        + f"E = {cfg.material.E:g}, ν = {cfg.material.nu:g}, α = {cfg.alpha:g}, ε = h, "
        f"u_ex = ({', '.join(f'`{c.text}`' for c in cfg.problem.exact)}), contact on the `{cfg.contact}` face. "
        "The P2 contact term is integrated as the scalar problem's: each Γ_C facet cut at the zeros of the "
        "quadratic w_h = u_h·n − g0 (on a triangle also where that conic is tangent to the rule's lines), "
        "w = u·n − g0. `pos_gc` = "
        "‖[w]_+ − [w_h]_+‖_{L³(Γ_C)}; `H1` the seminorm of the vector error.",
        "",
        "P1:",
        "",
        markdown(rows1, COLUMNS),
        "",
        "P2:",
        "",
        markdown(rows2, COLUMNS),
        "",
        f"Fitted over the last {rates.FIT_LEVELS} levels: P1 " + ", ".join(f"{n} {cells.rate(fit1[n])}" for n in NORMS)
        + "; P2 " + ", ".join(f"{n} {cells.rate(fit2[n])}" for n in NORMS) + "; all levels converged: "
        + cells.yes(all(r["converged"] for r in rows1 + rows2)) + ".",
        "",
        *rate_lines(fit1, fit2),
        f"- At N = {last2['N']}: P2 L2 {last2['L2']:.3e} and H1 {last2['H1']:.3e} with {last2['dofs']:,} dofs "
        f"against P1 L2 {last1['L2']:.3e} and H1 {last1['H1']:.3e} with {last1['dofs']:,} dofs.",
        *equal_dofs_lines(rows1, rows2),
    ])


def quadrature_section(p2, check):
    """The default exact rule against a Gauss rule: the relative change of every error, per level."""
    (_, cfg, rows), (path, other, rows_other) = p2, check
    changes = [max(abs(b[n] / a[n] - 1) for n in ("L2", "H1")) for a, b in zip(rows, rows_other)]
    return "\n".join([
        f"## The contact rule: {cfg.contact_quadrature} against a Gauss rule of degree {other.contact_quadrature}",
        "",
        f"`{path}` solves the P2 study with a Gauss rule of degree {other.contact_quadrature} on Γ_C. The largest "
        f"relative change of L2 or H1 per level: " + ", ".join(
            f"N = {r['N']}: {c:.1e}" for r, c in zip(rows, changes))
        + f". A Gauss rule across the kinks of [u_h]_+^α changes the discrete solution by up to {max(changes):.1e} "
        "of the discretisation error.",
    ])


def signorini_section(p1, p2, compliance1, compliance2):
    """Both elements against the Signorini solution u_S with the same eps = h: the total error, beside the
    finest levels of the manufactured compliance studies (discretisation error alone)."""
    (path1, cfg, rows1), (path2, _, rows2) = p1, p2
    p1_last, p2_last = compliance1[2][-1], compliance2[2][-1]
    fit1, fit2 = ({norm: fit(rows, norm) for norm in ("L2", "H1")} for rows in (rows1, rows2))
    columns = ("N", "epsilon", "dofs", "L2", "rate_L2", "H1", "rate_H1")
    last1, last2 = rows1[-1], rows2[-1]
    return "\n".join([
        "## Against the Signorini solution: the penalty's inconsistency",
        "",
        f"`{path1}` and `{path2}`: the same model (α = {cfg.alpha:g}, ε = h) with data f, u_D of the Signorini "
        "solution u_S of [signorini-solution.md](signorini-solution.md) and contact data g = 0, errors "
        "measured against u_S. The compliance model is not consistent with the Signorini problem: u_S − u_h "
        "holds the model error u_S − u_ε, O(ε^{1/α}) by the heuristic of [limit.md](limit.md) (section 2), "
        "besides the discretisation error.",
        "",
        "P1:",
        "",
        markdown(rows1, columns),
        "",
        "P2:",
        "",
        markdown(rows2, columns),
        "",
        f"Fitted over the last {rates.FIT_LEVELS} levels: P1 L2 {cells.rate(fit1['L2'])}, H1 {cells.rate(fit1['H1'])}; P2 L2 "
        f"{cells.rate(fit2['L2'])}, H1 {cells.rate(fit2['H1'])}, against the heuristic 1/α = {1 / cfg.alpha:.2f} "
        f"of the model error. At N = {last2['N']} P2's L2 error is {percent(last2['L2'], last1['L2'])} of P1's and its H1 "
        f"error {percent(last2['H1'], last1['H1'])}, where with the manufactured compliance solution above it is "
        f"{percent(p2_last['L2'], p1_last['L2'])} and {percent(p2_last['H1'], p1_last['H1'])}: "
        + ("with ε = h the model error, which no element reduces, sets the error of both elements."
           if abs(last2["L2"] / last1["L2"] - 1) < 0.1 else "P2 still reduces the error against u_S."),
    ])


def percent(part, whole):
    return f"{100 * part / whole:.1f} %"


def fit(rows, norm):
    return rates.fitted([r["h"] for r in rows], [r[norm] for r in rows], [r["converged"] for r in rows],
                        rates.FIT_LEVELS)


def keeps(fits, k):
    """Within 0.1 of both interpolation orders (the verdicts' default tolerance)."""
    return fits["L2"] is not None and fits["H1"] is not None and fits["L2"] >= k + 0.9 and fits["H1"] >= k - 0.1


def keeps_detail(fits, k):
    return f"L2 short of {k + 1} by {k + 1 - fits['L2']:.2f}, H1 short of {k} by {k - fits['H1']:.2f}"


def markdown(rows, columns):
    """A Markdown table: errors .3e, rates .2f, '–' where undefined."""
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(cell(c, row.get(c)) for c in columns) + " |" for row in rows]
    return "\n".join(lines)


def cell(column, value):
    if value is None:
        return "–"
    if column.startswith("rate_"):
        return f"{value:.2f}"
    if isinstance(value, float):
        return f"{value:.3e}"
    return str(value)


if __name__ == "__main__":
    sys.exit(main())
