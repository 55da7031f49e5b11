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
             "(`verification.fit_levels`, default 3), h the largest cell diameter. Its **interval** is derived "
             "from the data: it holds the fit ± 2 standard errors of the regression slope (about 95 % for "
             "normal residuals; with 3 levels the residual is the spread of the two successive rates itself), "
             "at least ± 0.02 (errors whose constant drifts by 3 % over three levels move their slope by "
             "ln(1.03)/ln 4 = 0.02; the demo's L2 constant e/h² drifts by 2.8 % over N = 32..128), "
             "every successive rate between the fitted levels, and the limit they head to: r(h) = p + c h^q through "
             "the last two rates at their h (√(h_{k−1} h_k)), q from the last three (log₂(3/2) when only one "
             "change is known, at least log₂(4/3)); in h, so any refinement ratios extrapolate. For halving h "
             "that is the last rate plus ρ/(1 − ρ) times its last change, ρ = 2^-q.", "",
             "A proven rate is an upper bound on the error, and the verdict compares the interval with it on "
             "both sides. Every definite class needs the same evidence, three fitted levels and an interval no "
             "wider than ± `verification.tolerance` (default 0.2 = half the smallest gap between two rates the "
             "paper proves for one norm, 8/5 and 2): `agrees` (the proven rate inside the interval); `exceeds` "
             "(the whole interval above: the bound is not sharp on this case, a finding); `below` (the whole "
             "interval below: a finding, or a hypothesis fails); `inconclusive` (too few levels, an interval "
             "too wide on either side, rates still moving towards a proven rate within the tolerance, or "
             "reference depths k and k − 1 giving different classes: the reason says which); `not covered` "
             "(the paper proves nothing here, or one of its hypotheses fails: the reason names it). Where the "
             "paper's bound carries |ln h| (d = 2, alpha > 2) the rate is still the plain slope; the interval "
             "also holds where the rates head if they approach the proven rate as p − b/|ln h|, and the slope "
             "of error/|ln h| is shown beside it (log-corrected).", "",
             "Data-only scenes measure each level against the same problem on its own mesh refined k times "
             "(`verification.reference_refinements`, default 2): once the rates settle, that distance is a "
             "fixed fraction of the level's error on every level, so the fitted rate does not depend on k "
             "(one reference k refinements beyond the *finest* level biased the finest levels' rates and made "
             "the verdict depend on k). The depth k − 1 errors are measured too and must give the same class; "
             "`ref_err_*` = ||u_ref(k−1) − u_ref(k)|| reports how exact each level's reference is.", "",
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
    """Rates better than proven (in Ω first: the headline), below, inconclusive, and rates where the paper
    is silent, each with its interval and the verdict's reason."""
    found = {"exceeds": ([], []), "below": ([], []), "inconclusive": ([], []), "not covered": ([], [])}
    for case in cases:
        for row in norm_rows(case):
            if row["verdict"] not in found or number(row["observed_rate"]) is None:
                continue
            line = (f"- `{case['cfg'].study}` {row['name']}: observed {rate(number(row['observed_rate']))} "
                    f"in {interval(row)}, proven {fraction(number(row['proven_rate']))}"
                    f"{' (' + row['paper'] + ')' if row['paper'] else ''}: {row['reason']}.")
            found[row["verdict"]][0 if base(row["name"]) in ("L2", "H1") else 1].append(line)
    lines = ["## Findings", ""]
    for verdict, title in (("exceeds", "Observed better than proven (`exceeds`)"), ("below", "Below the bound (`below`)"),
                           ("inconclusive", "Inconclusive"), ("not covered", "Observed where the paper proves nothing (`not covered`)")):
        in_omega, on_gc = found[verdict]
        lines += [f"### {title}", "", "In Ω:", ""] + (in_omega or ["- none"]) + ["", "On Γ_C:", ""] + (on_gc or ["- none"]) + [""]
    return lines


def interval(row):
    lo, hi = number(row.get("rate_lo")), number(row.get("rate_hi"))
    return "-" if lo is None else f"[{lo:.2f}, {hi:.2f}]"


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
    lines += ["", "| norm | observed | interval | proven | verdict | fitted levels (N) | paper | why |",
              "|---|---|---|---|---|---|---|---|"]
    for row in norm_rows(case):
        observed = rate(number(row["observed_rate"]))
        if row["log_factor"] is True:
            observed += f" (log-corrected {rate(number(row['log_corrected_rate']))})"
        proven = fraction(number(row["proven_rate"])) + (" · \\|ln h\\|" if row["log_factor"] is True else "")
        lines.append(f"| {row['name']} | {observed} | {interval(row)} | {proven} | {row['verdict']} | {row['levels']} | "
                     f"{row['paper'] or '-'} | {row['reason'].replace('|', chr(92) + '|')} |")
    lines += [""] + quantity_lines(case) + expect_lines(case)
    return lines


def quantity_lines(case):
    rows = [r for r in case["summary"] if r["kind"] == "quantity"]
    if not rows:
        return []
    v = case["cfg"].verification
    lines = [f"Reference solutions: each level's mesh refined {v.reference_refinements} times, reference_epsilon: "
             f"{v.reference_epsilon}.", "",
             "Quantities of interest on the three finest levels (observed order, Richardson extrapolation and "
             "Roache's GCI with safety factor 1.25, Celik et al. 2008):", "",
             "| quantity | levels (N) | finest | order | extrapolated | GCI_fine | error band |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        if not r["order"]:
            lines.append(f"| {r['name']} | {r['levels']} | - | - | - | - | {r['reason']} |")
            continue
        order = f"{float(r['order']):.2f}" + (" (oscillatory)" if r["oscillatory"] is True else "")
        lines.append(f"| {r['name']} | {r['levels']} | {float(r['value']):.6e} | {order} | "
                     f"{float(r['extrapolated']):.6e} | {100 * float(r['gci']):.3g}% | "
                     f"± {float(r['band']):.2e} |")
    slow = [r["name"] for r in rows if r["order"] and float(r["order"]) < 1]
    if slow:
        lines += ["", f"Apparent order below 1 for {', '.join(slow)}: these levels are not in the asymptotic "
                      "range the GCI assumes, so its band is no error bar."]
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
