"""docs/verification.md from the configs/paper studies' results: observed against proven rates, verdicts,
mesh sizes. Every number on the page comes from results/<study>/{rates,summary}.csv.

    python scripts/verification_page.py RESULTS_DIR CONFIG... > docs/verification.md

The observed rates live on the page only: the configs keep what the paper predicts, not what a run gave."""
import argparse
import sys
from fractions import Fraction
from pathlib import Path

import provenance
from signorini_cli import config
from signorini_cli.record import csvfile

OVERVIEW_NORMS = ("H1", "L2", "pos_gc_scaled", "energy_err")  # with _ref for data-only scenes


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", type=Path, help="folder holding one results folder per study")
    parser.add_argument("configs", nargs="+", type=Path)
    args = parser.parse_args(argv)
    cases = [load_case(path, args.results) for path in args.configs]
    sys.stdout.write(page(cases))
    return 0


def load_case(path, results):
    cfg = config.load(path)
    folder = results / cfg.study
    return {"path": path, "cfg": cfg, "folder": folder, "levels": read_csv(folder / "rates.csv"),
            "summary": read_csv(folder / "summary.csv")}


def read_csv(path):
    return csvfile.read(path) if path.exists() else []


def page(cases):
    lines = ["# Verification against Cantin & Hild (2020)", "",
             provenance.line("verify", [case["folder"] for case in cases]) + " Every number below is read "
             "from the `rates.csv` and `summary.csv` of the studies in `configs/paper/`.", "",
             "A rate is the least-squares slope of log(error) against log(h) over the last levels of a study "
             "(`verification.fit_levels`, default 3), h the largest cell diameter. A proven rate is an upper "
             "bound on the error: the verdict is `agrees` when observed >= proven - tolerance "
             "(`verification.tolerance`, default 0.1), `below theory` otherwise, and `not covered` where the "
             "paper proves nothing for that norm, dimension, alpha and eps law. Where the paper's bound carries "
             "|ln h| (d = 2, alpha > 2) the verdict uses the slope of error/|ln h|.", "",
             "Norms: `H1` = |u - u_h|_{H1(Ω)}, `L2` = ||u - u_h||_{L2(Ω)}, `L2_gc` = ||u - u_h||_{L2(Γ_C)}, "
             "`pos_gc` = ||[u]_+ - [u_h]_+||_{L^{α+1}(Γ_C)}, "
             "`pos_gc_scaled` = pos_gc^{(α+1)/2} (Cor. 3.2 ii), "
             "`energy_err` = (H1² + pos_gc^{α+1}/ε)^{1/2} (Lemma 3.1). A suffix `_ref` marks errors against a "
             "reference solution (data-only scenes), `diff_` the successive differences ||u_h - u_{h/2}||.", ""]
    lines += overview(cases) + findings(cases)
    for case in cases:
        lines += case_section(case)
    return "\n".join(lines) + "\n"


def overview(cases):
    lines = ["## Overview", "",
             "| case | d | α | ε | N | " + " | ".join(OVERVIEW_NORMS) + " |",
             "|---|---|---|---|---|" + "---|" * len(OVERVIEW_NORMS)]
    for case in cases:
        cfg, by_norm = case["cfg"], norms_of(case)
        suffix = "_ref" if cfg.problem.exact is None else ""
        cells = [short(by_norm.get(norm + suffix)) for norm in OVERVIEW_NORMS]
        lines.append(f"| [{cfg.study}](#{cfg.study}) | {cfg.dimension} | {cfg.alpha:g} | {cfg.epsilon.formula()} | "
                     f"{levels_text(case)} | " + " | ".join(cells) + " |")
    lines += ["", "Each cell: observed rate / proven rate, verdict (nc = not covered by the paper).", ""]
    return lines


def findings(cases):
    """Better than proven (in Ω first: the headline), below theory, rates where the paper is silent."""
    better, better_gc, below, uncovered = [], [], [], []
    for case in cases:
        tolerance = case["cfg"].verification.tolerance
        for row in norm_rows(case):
            observed, proven = number(row["observed_rate"]), number(row["proven_rate"])
            where = f"`{case['cfg'].study}` {row['name']}"
            if row["verdict"] == "below theory":
                below.append(f"- {where}: observed {rate(observed)}, proven {fraction(proven)} ({row['paper']}).")
            elif proven is not None and observed is not None and observed > proven + tolerance:
                line = (f"- {where}: observed {rate(observed)}, the paper proves {fraction(proven)} "
                        f"({row['paper']}): **better than proven**.")
                if row["log_factor"] is True:  # the fit of e/|ln h| exceeds the plain slope by construction
                    plain = rate(number(row["plain_rate"]))
                    line = (f"- {where}: plain slope {plain}, {rate(observed)} for e/\\|ln h\\|; the paper proves "
                            f"O(h^{fraction(proven)} \\|ln h\\|) ({row['paper']}): the error decays as h^{plain} "
                            "without the bound's \\|ln h\\| factor, **better than proven** by that factor.")
                (better if base(row["name"]) in ("L2", "H1") else better_gc).append(line)
            elif row["verdict"] == "not covered" and observed is not None:
                uncovered.append(f"- {where}: observed {rate(observed)}; {row['conditions']}.")
    return (["## Findings", "", "### Observed better than proven", "", "In Ω:", ""] + (better or ["- none"]) +
            ["", "On Γ_C:", ""] + (better_gc or ["- none"]) +
            ["", "### Below theory", ""] + (below or ["- none: every proven rate is reached"]) +
            ["", "### Observed where the paper proves nothing", ""] + (uncovered or ["- none"]) + [""])


def base(norm):
    return norm.removeprefix("diff_").removesuffix("_ref")


def case_section(case):
    cfg = case["cfg"]
    lines = [f"## {cfg.study}", "", f"{cfg.description}. Config: `{case['path']}`; d = {cfg.dimension}, "
             f"α = {cfg.alpha:g}, ε = {cfg.epsilon.formula()}, Γ_C = {cfg.contact} face.", ""]
    if not case["levels"]:
        return lines + ["(no results: the study has not been run)", ""]
    lines += ["| level | N | h | dofs | ε | converged | Newton its |", "|---|---|---|---|---|---|---|"]
    for lv in case["levels"]:
        lines.append(f"| {lv['level']} | {lv['N']} | {float(lv['h']):.4e} | {lv['dofs']} | "
                     f"{float(lv['epsilon']):.3e} | {str(lv['converged']).lower()} | {lv['newton_its']} |")
    lines += ["", "| norm | observed | proven | verdict | fitted levels (N) | paper | conditions |",
              "|---|---|---|---|---|---|---|"]
    for row in norm_rows(case):
        observed = rate(number(row["observed_rate"]))
        if row["log_factor"] is True:
            observed += f" (of e/\\|ln h\\|; plain {rate(number(row['plain_rate']))})"
        proven = fraction(number(row["proven_rate"])) + (" · \\|ln h\\|" if row["log_factor"] is True else "")
        lines.append(f"| {row['name']} | {observed} | {proven} | {row['verdict']} | {row['levels']} | "
                     f"{row['paper'] or '-'} | {row['conditions'].replace('|', '/')} |")
    lines += [""] + quantity_lines(case) + expect_lines(case)
    return lines


def quantity_lines(case):
    rows = [r for r in case["summary"] if r["kind"] == "quantity"]
    if not rows:
        return []
    v = case["cfg"].verification
    n_ref = case["cfg"].mesh.refinements[-1] * 2 ** v.reference_refinements
    lines = [f"Reference solution: N = {n_ref} ({v.reference_refinements} uniform refinements of the finest "
             f"level), reference_epsilon: {v.reference_epsilon}.", "",
             "Quantities of interest on the three finest levels (observed order, Richardson extrapolation and "
             "Roache's GCI with safety factor 1.25, Celik et al. 2008):", "",
             "| quantity | levels (N) | finest | order | extrapolated | GCI_fine | error band |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        if not r["order"]:
            why = "no order observable" if len(r["levels"].split()) == 3 else "needs three converged levels"
            lines.append(f"| {r['name']} | {r['levels']} | - | - | - | - | {why} |")
            continue
        order = f"{float(r['order']):.2f}" + (" (oscillatory)" if r["oscillatory"] is True else "")
        lines.append(f"| {r['name']} | {r['levels']} | {float(r['value']):.6e} | {order} | "
                     f"{float(r['extrapolated']):.6e} | {100 * float(r['gci']):.3g}% | "
                     f"± {float(r['band']):.2e} |")
    slow = [r["name"] for r in rows if r["order"] and float(r["order"]) < 1]
    if slow:
        lines += ["", f"Apparent order below 1 for {', '.join(slow)}: these levels are not in the asymptotic "
                      "range the GCI assumes, so its band is no error bar. Where eps depends on h, each level "
                      "also solves a different continuous problem and the quantity follows the model's change "
                      "with eps (the diff_* rates show the same)."]
    return lines + [""]


def expect_lines(case):
    rows = [r for r in case["summary"] if r["kind"] == "expect"]
    if not rows:
        return []
    met = ", ".join(f"{r['name']} >= {r['expected_rate']} - {r['tolerance']}: "
                    f"{'met' if r['met'] == 'true' else '**not met**'}" for r in rows)
    return [f"`expect:` {met}.", ""]


def norm_rows(case):
    return [r for r in case["summary"] if r["kind"] == "norm"]


def norms_of(case):
    return {r["name"]: r for r in norm_rows(case)}


def short(row):
    if row is None:
        return "-"
    verdict = {"not covered": "nc"}.get(row["verdict"], row["verdict"])
    return f"{rate(number(row['observed_rate']))} / {fraction(number(row['proven_rate']))}, {verdict}"


def levels_text(case):
    ns = [lv["N"] for lv in case["levels"]]
    return f"{ns[0]}–{ns[-1]}" if ns else "-"


def number(text):
    return float(text) if text not in ("", None) else None


def rate(value):
    return "-" if value is None else f"{value:.2f}"


def fraction(value):
    """A proven rate as the paper writes it: 8/5, 3/2, 2."""
    if value is None:
        return "-"
    f = Fraction(value).limit_denominator(12)
    return str(f) if abs(float(f) - value) < 1e-9 else f"{value:.3g}"


if __name__ == "__main__":
    sys.exit(main())
