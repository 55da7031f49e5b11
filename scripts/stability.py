"""`make stiff`: run the stiff suite, the regular studies, a smoothing (delta) sweep and a conditioning
sweep, and write docs/stability.md from the runs. Every number in that page comes from here."""
import argparse
import dataclasses
import json
import math
import os
import platform
import re
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import yaml

import provenance
from signorini_cli import config
from signorini_cli.analysis import rates
from signorini_cli.record import csvfile, h5

ROOT = Path(__file__).resolve().parent.parent
EASY_ITS = 3  # the issue's target: at most 3 Newton iterations after the first level with strategy auto
# relative L2 difference between strategies' solutions: solver tolerance allows stol ||u|| / ||u - u_h||
# (1e-7 * 0.32 / 2.5e-5 = 1.3e-3 at N = 256); a solve stopped away from the solution is off by factors
STRATEGIES_AGREE = 1e-2
DELTAS = ("exact", "1e-12", "1e-2*h**2", config.DEFAULT_DELTA, "h*sqrt(eps)", "1e-2*h", "h")
DELTA_CASES = (("1.0", "theta_h", "1.0"), ("1.0", "constant", "1.0e-8"), ("1.0", "theta_h", "1000.0"),
               ("2.0", "theta_h", "1.0"), ("2.0", "constant", "1.0e-8"), ("2.0", "theta_h", "1000.0"))
DELTA_LEVELS = "[8, 16, 32, 64, 128]"
DELTA_HARMLESS = 1e-4  # relative change of the finest L2 error that smoothing may cause: far below the rates' noise
CONDITION_EPS = ("1.0e-1", "1.0e-2", "1.0e-4", "1.0e-6", "1.0e-8")
CONDITION_LEVELS = "[8, 16, 32, 64]"


@dataclass(frozen=True)
class Runs:
    """Where runs go (`runs / "name"` is a sub-folder), and whether finished earlier runs of the same
    config may be read back instead of run again (--reuse)."""
    root: Path
    reuse: bool = False

    def __truediv__(self, name):
        return dataclasses.replace(self, root=self.root / name)


def run(path, out, overrides=()):
    """Run one study through the command line (in a process of its own) into the Runs `out`; return
    (exit status, rows of its rates.csv)."""
    status, tables = run_tables(path, out, overrides)
    return status, tables["rates"]


def run_tables(path, out, overrides=()):
    """Run one study as `signorini run` (run_apart); return (its exit status, {table name: rows}) of every CSV
    it wrote (rates for refinement studies; sweep, fitted and reference
    for an ε-sweep)."""
    cfg = config.load(path, list(overrides) + [f"output.dir={out.root}"])
    status = reused(cfg) if out.reuse else None
    if status is None:
        status = run_apart(path, out.root, overrides)
    tables = {}
    for csv_path in sorted(cfg.output_dir.glob("*.csv")):
        tables[csv_path.stem] = csvfile.read(csv_path)
    return status, tables


def run_apart(path, folder, overrides):
    """`signorini run` of the config in a process of its own: its exit status (0, or 1 where a level did not
    converge or an `expect:` missed). The page runs some 150 studies, 3-D gmsh ones among them: in one process
    the memory they leave behind adds up (17 GB, which the kernel's OOM killer ended)."""
    command = [str(Path(sys.executable).parent / "signorini"), "run", str(path), "--quiet", "--force",
               "--output", str(folder)] + [arg for override in overrides for arg in ("--set", override)]
    status = subprocess.run(command, check=False).returncode
    if status not in (0, 1):
        raise SystemExit(f"{' '.join(command)}: exit status {status}")
    return status


def reused(cfg):
    """The exit status of a finished earlier run of exactly this config (same hash), or None. Only for
    reworking the page: the hash does not see changes to the code."""
    path = cfg.output_dir / "study.h5"
    if not path.exists():
        return None
    record = h5.read(path)
    if record.attrs.get("config_hash") != config.fingerprint(cfg) or record.attrs.get("status") != "complete":
        return None
    return 0 if all(row["converged"] for row in record.tables.get(record.main, [])) else 1


def fmt(value, spec=".3e"):
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "**no**"
    return f"{value:{spec}}" if isinstance(value, float) else str(value)


def table(header, lines):
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(str(c) for c in line) + " |" for line in lines]
    return "\n".join(out)


# --- the stiff suite ----------------------------------------------------------------------------------

def stiff_suite(out):
    """Each configs/stiff study with strategy auto (the default), plain Newton, and continuation from 0."""
    cases = []
    for path in sorted((ROOT / "configs" / "stiff").glob("*.yaml")):
        auto = run(path, out / "auto")
        plain = run(path, out / "plain", ["solver.strategy=plain"])
        continuation = run(path, out / "continuation", ["solver.strategy=continuation"])
        cases.append((path, config.load(path), auto, plain, continuation))
    return cases


def stiff_section(cases):
    lines = ["## The stiff suite (`configs/stiff/`)", "",
             "Each study with `strategy: auto` (the default) and, for comparison, `strategy: plain` (Newton "
             "from 0 with the bt line search on every level) and `strategy: continuation` (ε-continuation from 0 "
             "on every level). Newton and linear iterations count every solve of the level; 'L2 apart' is the "
             f"largest relative difference of L2 between the three on levels they all solved (bold above "
             f"{STRATEGIES_AGREE:g}: one of them stopped away from the solution). With ε ≪ h the "
             "residual carries 1/ε: `final ‖δ‖/‖u‖`, the last Newton correction, is the error estimate the "
             "success test used.", "",
             summary_table(cases), ""]
    for path, cfg, (status, rows), (_, plain_rows), _ in cases:
        lines += [f"### {path.stem}: {cfg.description}", "", f"`{path.relative_to(ROOT)}`, exit status {status}.", "",
                  level_table(rows, plain_rows), ""]
        lines += [f"Level {r['level']} (N={r['N']}) did not converge: {r['reason']}." for r in rows if not r["converged"]]
    return "\n".join(lines)


def summary_table(cases):
    header = ["case", "finest N", "auto: all converged", "auto: max Newton its after level 0",
              "auto: Newton its (total)", "plain: levels failed", "plain: Newton its (total)",
              "continuation: levels failed", "continuation: Newton its (steps)", "L2 apart (strategies)",
              "finest L2", "last rate L2", "last rate H1"]
    lines = []
    for path, _, (_, rows), (_, plain), (_, cont) in cases:
        lines.append([path.stem, rows[-1]["N"], fmt(all(r["converged"] for r in rows)),
                      max((r["newton_its"] for r in rows[1:]), default="–"), sum(r["newton_its"] for r in rows),
                      sum(not r["converged"] for r in plain), sum(r["newton_its"] for r in plain),
                      sum(not r["converged"] for r in cont),
                      f"{sum(r['newton_its'] for r in cont)} ({sum(r['continuation_steps'] for r in cont)})",
                      apart(rows, plain, cont), fmt(rows[-1].get("L2")), fmt(rows[-1].get("rate_L2"), ".2f"), fmt(rows[-1].get("rate_H1"), ".2f")])
    return table(header, lines)


def apart(*runs):
    """The largest relative difference of L2 between strategies on the levels all of them converged:
    the same discrete solution must come out of each (bold when above STRATEGIES_AGREE)."""
    diffs = [abs(max(l2) - min(l2)) / min(l2) for l2 in
             ([r.get("L2") for r in level] for level in zip(*runs)) if all(v for v in l2)]
    if not diffs:
        return "–"
    return fmt(max(diffs), ".0e") if max(diffs) <= STRATEGIES_AGREE else f"**{fmt(max(diffs), '.0e')}**"


def level_table(rows, plain_rows):
    header = ["N", "ε", "converged", "Newton its", "linear its", "continuation steps", "final ‖F‖",
              "final ‖δ‖/‖u‖", "reason", "max [u_h]_+ on Γ_C", "cond(J)", "L2", "rate L2", "H1", "rate H1",
              "plain: Newton its (reason)"]
    lines = []
    for r, p in zip(rows, plain_rows):
        lines.append([r["N"], fmt(r["epsilon"], ".2e"), fmt(r["converged"]), r["newton_its"], r["linear_its"],
                      fmt(r.get("continuation_steps")), fmt(r["final_residual"], ".1e"),
                      fmt(r.get("final_correction"), ".1e"), r["reason"],
                      fmt(r["penetration"], ".4f"), fmt(r.get("condition"), ".2e"), fmt(r.get("L2")),
                      fmt(r.get("rate_L2"), ".2f"), fmt(r.get("H1")), fmt(r.get("rate_H1"), ".2f"),
                      f"{p['newton_its']} ({p['reason']})"])
    return table(header, lines)


# --- the regular studies -----------------------------------------------------------------------------

def regular_studies(out):
    """The shipped paper studies (configs/*.yaml, configs/paper/*.yaml) with auto and with plain; the
    gmsh geometries (configs/gmsh/*.yaml) with auto."""
    paper = sorted((ROOT / "configs").glob("*.yaml")) + sorted((ROOT / "configs" / "paper").glob("*.yaml"))
    gmsh = sorted((ROOT / "configs" / "gmsh").glob("*.yaml"))
    return ([(path, run(path, out / "auto", ["solver.strategy=auto"]), run(path, out / "plain", ["solver.strategy=plain"]))
             for path in paper],
            [(path, run(path, out / "auto", ["solver.strategy=auto"])) for path in gmsh])


def regular_section(paper, gmsh):
    header = ["study", "N", "auto: Newton its per level", "auto: max after level 0", f"≤ {EASY_ITS}",
              "plain: Newton its per level", "all converged"]
    lines, met = [], True
    for path, (_, rows), (_, plain) in paper:
        after_first = max((r["newton_its"] for r in rows[1:]), default=0)
        met &= after_first <= EASY_ITS and all(r["converged"] for r in rows)
        lines.append([path.relative_to(ROOT / "configs").with_suffix(""), ", ".join(str(r["N"]) for r in rows),
                      ", ".join(str(r["newton_its"]) for r in rows), after_first, fmt(after_first <= EASY_ITS),
                      ", ".join(str(r["newton_its"]) for r in plain), fmt(all(r["converged"] for r in rows))])
    verdict = (f"Every regular study needs at most {EASY_ITS} Newton iterations on every level after the first "
               "with `strategy: auto`." if met else
               f"**Not met**: some regular study needs more than {EASY_ITS} Newton iterations after the first level.")
    return "\n".join(["## Regular studies: Newton iterations with nested iteration", "",
                      "The shipped paper studies, solved with `strategy: auto` (nested iteration: each level starts "
                      "from the previous level's solution) and with `strategy: plain` (each level from 0).", "",
                      table(header, lines), "", verdict, "", gmsh_table(gmsh)])


def gmsh_table(gmsh):
    """The gmsh geometries: curved or re-entrant boundaries, unstructured or nested families."""
    lines = [[path.relative_to(ROOT / "configs").with_suffix(""), ", ".join(str(r["N"]) for r in rows),
              ", ".join(str(r["newton_its"]) for r in rows), max((r["newton_its"] for r in rows[1:]), default=0),
              fmt(all(r["converged"] for r in rows))] for path, (_, rows) in gmsh]
    return "\n".join(["The gmsh geometries (`configs/gmsh/`, with `strategy: auto`; N is the level's `N` column) "
                      "are not part of that target: on unstructured or curved families the previous level's "
                      "solution is interpolated (and extended beyond a curved boundary the coarser mesh does "
                      "not reach), not carried over exactly.", "",
                      table(["study", "N", "auto: Newton its per level", "auto: max after level 0", "all converged"],
                            lines)])


# --- smoothing --------------------------------------------------------------------------------------

def delta_sweep(out):
    """The demo problem with each delta law, for alpha in {1, 2} and three eps laws; plain and auto."""
    results = {}
    for alpha, law, theta in DELTA_CASES:
        for delta in DELTAS:
            pp = "positive_part=exact" if delta == "exact" else f"positive_part={{kind: smooth, delta: '{delta}'}}"
            base = [f"alpha={alpha}", f"epsilon.law={law}", f"epsilon.theta={theta}", pp,
                    f"mesh.refinements={DELTA_LEVELS}"]
            name = re.sub(r"[^0-9a-z.]+", "_", f"alpha{alpha}-{law}{theta}-{delta}")  # one folder per variant
            results[(alpha, law, theta, delta)] = {
                strategy: run(ROOT / "configs" / "demo.yaml", out / strategy / name,
                              base + [f"solver.strategy={strategy}"])[1]
                for strategy in ("plain", "auto")}
    return results


def delta_section(results):
    finest = next(iter(results.values()))["auto"][-1]["N"]
    header = ["α", "ε", "δ", f"L2 (N={finest})", "L2 change vs exact", "rate L2", "rate H1",
              "plain: Newton its per level", "auto: Newton its per level"]
    lines, summary = [], {}
    for (alpha, law, theta, delta), runs in results.items():
        auto, plain = runs["auto"], runs["plain"]
        exact = results[(alpha, law, theta, "exact")]["auto"][-1]["L2"]
        change = abs(auto[-1]["L2"] - exact) / exact if auto[-1]["L2"] is not None else math.inf
        row = summary.setdefault(delta, {"changes": {}, "failed": 0, "plain": 0, "auto": 0})
        label = eps_label(law, theta)
        row["changes"][label] = max(row["changes"].get(label, 0.0), change)
        row["failed"] += sum(not r["converged"] for r in plain + auto)
        row["plain"] += sum(r["newton_its"] for r in plain)
        row["auto"] += sum(r["newton_its"] for r in auto)
        lines.append([alpha, label, f"`{delta}`", fmt(auto[-1]["L2"]), fmt(change, ".1e"),
                      fmt(auto[-1]["rate_L2"], ".2f"), fmt(auto[-1]["rate_H1"], ".2f"),
                      ", ".join(str(r["newton_its"]) + ("" if r["converged"] else " **failed**") for r in plain),
                      ", ".join(str(r["newton_its"]) for r in auto)])
    return "\n".join(["## Smoothing the positive part: the choice of δ", "",
                      "`positive_part: {kind: smooth, delta: …}` replaces [u]_+ by (u + √(u² + δ²))/2. Off contact "
                      "(u < 0) that is δ²/(4|u|) instead of 0, a boundary flux error δ²/(4ε|u|) once divided by ε; "
                      "at the kink it is δ/2. The demo problem (u = sin(2πx)(1−y)², Γ_C at y = 0), "
                      f"N = {DELTA_LEVELS}; 'L2 change' is |L2(δ) − L2(exact)| / L2(exact) on the finest level.", "",
                      table(header, lines), "", delta_verdict(summary)])


def eps_label(law, theta):
    return {"theta_h": f"{float(theta):g} h", "constant": f"{float(theta):g}"}[law]


def delta_verdict(summary):
    labels = list(next(iter(summary.values()))["changes"])
    header = ["δ"] + [f"largest L2 change, ε = {label}" for label in labels] + [
        "levels failed (plain and auto)", "plain: Newton its (total)", "auto: Newton its (total)"]
    lines = [[f"`{delta}`"] + [fmt(row["changes"][label], ".1e") for label in labels] +
             [row["failed"], row["plain"], row["auto"]] for delta, row in summary.items()]
    default = config.DEFAULT_DELTA
    harmless = [d for d, row in summary.items() if d != "exact" and max(row["changes"].values()) < DELTA_HARMLESS]
    robust = min(harmless, key=lambda d: (summary[d]["failed"], summary[d]["plain"]), default=None)
    return "\n".join([table(header, lines), "",
                      f"Laws that move the finest L2 error by less than {DELTA_HARMLESS:g} relative in every case: "
                      + (", ".join(f"`{d}`" for d in harmless) or "none") + ". "
                      f"Among them the fewest failed levels and plain-Newton iterations: `{robust}`. "
                      f"The default, `delta: {default}` (`config.DEFAULT_DELTA`), moves it by at most "
                      f"{fmt(max(summary[default]['changes'].values()), '.1e')}, with "
                      f"{summary[default]['failed']} failed levels against {summary['exact']['failed']} for the exact "
                      "positive part. It is the δ² ∝ h²ε law: the off-contact flux error δ²/ε is then O(h²) "
                      "for every ε, where laws in h alone grow as ε → 0."])


# --- conditioning -----------------------------------------------------------------------------------

def condition_sweep(out):
    """cond(J) at the solution against eps (constant) and against h (eps = h and eps = 1e-8)."""
    base = [f"mesh.refinements={CONDITION_LEVELS}", "solver.condition_max_dofs=5000"]
    demo = ROOT / "configs" / "demo.yaml"
    by_eps = {eps: run(demo, out / f"eps{eps}", base + ["epsilon.law=constant", f"epsilon.theta={eps}"])[1]
              for eps in CONDITION_EPS}
    by_h = {"ε = h": run(demo, out / "theta_h", base)[1], "ε = 1e-8": by_eps["1.0e-8"]}
    return by_eps, by_h


def condition_section(by_eps, by_h):
    ns = [r["N"] for r in next(iter(by_eps.values()))]
    header = ["ε"] + [f"N = {n}" for n in ns]
    lines = [[eps_label("constant", eps)] + [fmt(r["condition"], ".3e") for r in rows] for eps, rows in by_eps.items()]
    slopes_eps = [slope(*zip(*[(float(e), rows[k]["condition"]) for e, rows in by_eps.items()
                               if float(e) < rows[k]["h"] / 10])) for k in range(len(ns))]
    lines.append(["slope d log cond / d log ε, over ε < h/10"] + [fmt(s, ".2f") for s in slopes_eps])
    h_lines = [[name, ", ".join(fmt(r["condition"], ".3e") for r in rows),
                fmt(slope([r["h"] for r in rows], [r["condition"] for r in rows]), ".2f")] for name, rows in by_h.items()]
    return "\n".join(["## Conditioning of the Jacobian", "",
                      "λ_max/λ_min of the Jacobian at the converged solution on the free dofs (Lanczos estimate from "
                      "unpreconditioned CG, `solver.condition_max_dofs`), demo problem α = 2. Against ε (constant):",
                      "", table(header, lines), "", "Against h (fitted slope of log cond against log h):", "",
                      table(["ε law", "cond(J) for N = " + ", ".join(map(str, ns)), "slope"], h_lines), "",
                      "Expected: for ε ≪ h the penalised boundary rows dominate, λ_max ∝ h/ε and λ_min ∝ h², so "
                      "cond ∝ 1/(εh) (slope −1 in ε and in h); for ε = h the Laplacian's h⁻² (slope −2 in h). "
                      "The slopes above are the measurement. A direct solve (MUMPS) does not see the conditioning; "
                      "CG does, through its preconditioner, which is why an iterative failure falls back to MUMPS."])


def slope(x, y):
    """Least-squares slope of log y against log x over every point."""
    return rates.slope(x, y, k=len(x))


# --- contact quadrature rules ---------------------------------------------------------------------

RULES = ("exact", "vertex", "6")  # contact_quadrature: exact integration, the lumped nodal rule, Gauss degree 6
RULE_EPS = ("h", "1.0e-2", "1.0e-4", "1.0e-6", "1.0e-8", "1.0e-10", "1.0e-12", "1.0e-14")  # "h": ε = h
RULE_CASES = ((2, "1.0"), (2, "2.0"), (2, "3.0"), (3, "2.0"))  # (d, α): the issue's four
RULE_LEVELS = {2: "[8, 16, 32, 64]", 3: "[4, 8, 16]"}
RULE_CONFIGS = {2: ROOT / "configs" / "demo.yaml", 3: ROOT / "configs" / "cube-alpha2-theta-h.yaml"}
# h/ε classes of the gap summary: the paper's hypothesis is h/ε bounded
H_OVER_EPS = ((0.0, 1.0), (1.0, 1e4), (1e4, math.inf))
# the ε → 0 limit: ε-sweeps against the VI's u_{S,h} on fixed meshes (study_type epsilon_sweep)
LIMIT_EPS = {"start": 1.0e-2, "stop": 1.0e-14, "count": 7}
LIMIT_2D = ROOT / "configs" / "limit" / "sweep.yaml"
LIMIT_3D = {"study": "limit-sweep-3d", "study_type": "epsilon_sweep", "dimension": 3,
            "description": "3-D model error against the VI, f = 10 sin(2 pi x): contact on part of Γ_C",
            "mesh": {"kind": "unit_cube", "refinements": [4, 8]}, "contact": "bottom",
            "problem": {"f": "10*sin(2*pi*x)"}, "limit": {"alpha": [2], "epsilon": LIMIT_EPS}}
LIMIT_LEVELS = {2: "[16, 32]", 3: "[4, 8]"}
# the rule's solutions tend to u_{S,h} when the model error still falls over the smallest ε, at least like
# ε^0.1 (the fitted slope; the proof of Lemma 2.5, b(u_ε, u_ε) ≲ ε, gives ε^{1/(α+1)} >= ε^0.25 for the
# penetration); a rule whose limit is another function stalls there at a slope near 0
TENDS_SLOPE = 0.1


def rule_runs(out, cases=RULE_CASES, eps_values=RULE_EPS, levels=RULE_LEVELS):
    """Each case (d, α) at each ε with each contact rule: {(d, α, ε, rule): rows}."""
    found = {}
    for dim, alpha in cases:
        for eps in eps_values:
            for rule in RULES:
                law = ["epsilon.law=theta_h", "epsilon.theta=1.0"] if eps == "h" else \
                    ["epsilon.law=constant", f"epsilon.theta={eps}"]
                base = law + [f"alpha={alpha}", "output.plots=false",
                        f"mesh.refinements={levels[dim]}", f"contact_quadrature={rule}"]
                name = f"d{dim}-alpha{alpha}-eps{eps}-{rule}"
                found[(dim, alpha, eps, rule)] = run(RULE_CONFIGS[dim], out / name, base)[1]
    return found


def eps_name(eps):
    return "h" if eps == "h" else fmt(float(eps), ".0e")


def gap(rows, exact_rows):
    """|L2(rule) − L2(exact)| / L2(exact) per level (None where either did not converge)."""
    return [abs(r["L2"] - e["L2"]) / e["L2"] if r["converged"] and e["converged"] and r["L2"] and e["L2"]
            else None for r, e in zip(rows, exact_rows)]


def rule_case_table(found, dim, alpha):
    """One row per (ε, level): each rule's L2, its rate, Newton its and penetration, and the gaps."""
    columns = ("L2", "rate", "its", "max [u_h]_+")
    header = ["ε", "N", "h/ε"] + [f"{rule}: {col}" for rule in RULES for col in columns] + \
        [f"gap {rule}" for rule in RULES[1:]]
    lines = []
    for eps in RULE_EPS:
        runs = {rule: found[(dim, alpha, eps, rule)] for rule in RULES}
        gaps = {rule: gap(runs[rule], runs["exact"]) for rule in RULES[1:]}
        for k, r in enumerate(runs["exact"]):
            cells = [eps_name(eps), r["N"], fmt(r["h"] / r["epsilon"], ".1e")]
            for rule in RULES:
                row = runs[rule][k]
                cells += [fmt(row.get("L2")) + ("" if row["converged"] else " **not converged**"),
                          fmt(row.get("rate_L2"), ".2f"), row["newton_its"], fmt(row.get("penetration"), ".2e")]
            lines.append(cells + [fmt(gaps[rule][k], ".1e") for rule in RULES[1:]])
    return table(header, lines)


def gap_summary(found):
    """The largest gap of each rule to the exact one, by case and class of h/ε."""
    header = ["d, α", "rule"] + [f"largest gap, h/ε > {lo:g}" if hi == math.inf else
                                 f"largest gap, {lo:g} < h/ε ≤ {hi:g}" for lo, hi in H_OVER_EPS] + \
        ["levels not converged"]
    lines = []
    for dim, alpha in RULE_CASES:
        for rule in RULES[1:]:
            worst = {band: None for band in H_OVER_EPS}
            failed = 0
            for eps in RULE_EPS:
                rows, exact = found[(dim, alpha, eps, rule)], found[(dim, alpha, eps, "exact")]
                failed += sum(not r["converged"] for r in rows)
                for r, g in zip(rows, gap(rows, exact)):
                    band = next(b for b in H_OVER_EPS if b[0] < r["h"] / r["epsilon"] * (1 - 1e-12) <= b[1])
                    if g is not None:
                        worst[band] = max(g, worst[band] or 0.0)
            lines.append([f"{dim}-D, {float(alpha):g}", rule] + [fmt(worst[b], ".1e") for b in H_OVER_EPS] + [failed])
    exact_failed = sum(not r["converged"] for key, rows in found.items() if key[3] == "exact" for r in rows)
    return table(header, lines), exact_failed


# two independent libraries (scikit-fem, NGSolve; agreeing to 5e-12) integrating the contact term
# exactly, 2-D, α = 1, ε = 1e-8, u = sin(2πx)(1−y)²: L2 error at N = 16 and 64
INDEPENDENT = {16: 5.800452e-3, 64: 4.055548e-4}


def independent_check(found):
    """The exact rule's L2 at 2-D, α = 1, ε = 1e-8 against INDEPENDENT, as a sentence."""
    rows = {r["N"]: r for r in found.get((2, "1.0", "1.0e-8", "exact"), [])}
    said = [f"N = {n}: {fmt(rows[n]['L2'], '.6e')} against {value:.6e} (relative difference "
            f"{fmt(relative_difference(rows[n]['L2'], value), '.1e')})" for n, value in INDEPENDENT.items()
            if n in rows and rows[n].get("L2") is not None]
    return ("The exact rule against two independent implementations that integrate the term exactly ("
            "scikit-fem and NGSolve, 2-D, α = 1, ε = 1e-8): " + ("; ".join(said) or "not run") + ".")


def relative_difference(value, reference):
    return abs(value - reference) / abs(reference)


def rules_section(found):
    summary, exact_failed = gap_summary(found)
    lines = ["## The contact term: exact integration against the vertex rule and a Gauss rule", "",
             "The compliance term (1/ε)∫_Γc [u_h]_+^α v of the P1 solution, integrated three ways "
             "(`contact_quadrature`): `exact` (the default: the integral of the weak form, cut at the zero of "
             "u_h on each Γ_C facet), `vertex` (the lumped, nodal penalty common in contact codes: weights |F|/d at "
             "the d vertices of each facet F) and `6` (a Gauss rule of degree 6, the product's former default). "
             "ε = h (the paper's regime, h/ε = 1) and constant ε from 1e-2 to 1e-14; 2-D: u = sin(2πx)(1−y)² "
             "on N = " + RULE_LEVELS[2] + ", 3-D: u = sin(2πx)sin(πy)(1−z)² on N = " + RULE_LEVELS[3] +
             ". 'gap' is |L2(rule) − L2(exact)| / L2(exact) on the same level; 'max [u_h]_+' the penetration, "
             "a vertex value.", "",
             summary, "",
             f"Levels of the exact rule that did not converge: {exact_failed}. {independent_check(found)}", "",
             "Why they part: on facets where u_h keeps one sign, [u_h]_+^α v is 0 or u_h^α v, for integer α a "
             "polynomial of degree α + 1 that the degree-6 rule integrates exactly (α ≤ 5), while the vertex rule "
             "lumps it (an O(h²) relative change, as mass lumping); on facets where u_h changes sign [u_h]_+^α "
             "has a kink that no fixed rule integrates exactly. The difference of the "
             "integrals is a perturbation of the equations multiplied by 1/ε, against a stiffness of order 1 "
             "per unit length of Γ_C: its effect on u_h can grow with h/ε, and the classes above measure how "
             "much it does. The paper's estimates assume h/ε bounded "
             "(ε ≳ h); the first class above is that regime, the last the one where the stiffness of the penalty "
             "rows dominates and the rule decides the constraint u_h meets on Γ_C (next section)."]
    for dim, alpha in RULE_CASES:
        lines += ["", f"### {dim}-D, α = {float(alpha):g}", "", rule_case_table(found, dim, alpha)]
    return "\n".join(lines)


def limit_runs(out):
    """The ε-sweeps (2-D: configs/limit/sweep.yaml, α = 1, 2, 3; 3-D: LIMIT_3D, α = 2) with each rule:
    {(d, rule): tables}."""
    out.root.mkdir(parents=True, exist_ok=True)
    path_3d = out.root / "sweep-3d.yaml"
    path_3d.write_text(yaml.safe_dump(LIMIT_3D))
    found = {}
    for dim, path in ((2, LIMIT_2D), (3, path_3d)):
        for rule in RULES:
            base = [f"limit.epsilon={json.dumps(LIMIT_EPS)}", f"mesh.refinements={LIMIT_LEVELS[dim]}",
                    "output.plots=false", f"contact_quadrature={rule}"]
            found[(dim, rule)] = run_tables(path, out / f"d{dim}-{rule}", base)[1]
    return found


def limit_summary(found):
    """Per rule, case and mesh: the model error ‖u_{ε,h} − u_{S,h}‖_L2 and the penetration at the largest and
    the smallest ε, their ratio, the fitted slope in ε, and whether the rule's solutions tend to u_{S,h}."""
    header = ["d", "α", "N", "rule", "L2 diff, ε = 1e-2", "L2 diff, ε = 1e-14", "ratio", "fitted slope",
              "max [u_h]_+ at ε = 1e-14", "not converged", "tends to u_S,h"]
    lines, verdict = [], {}
    for (dim, rule), tables in found.items():
        groups = {}
        for row in tables["sweep"]:
            groups.setdefault((row["alpha"], row["N"]), []).append(row)
        fits = {(r["alpha"], r["N"]): r.get("fit_L2") for r in tables["fitted"]}
        for (alpha, n), rows in groups.items():
            first, last = rows[0], rows[-1]
            ratio = last["L2"] / first["L2"] if first.get("L2") and last.get("L2") is not None else None
            fit = fits.get((alpha, n))
            tends = fit is not None and fit >= TENDS_SLOPE and last["converged"]
            verdict.setdefault(rule, []).append(tends)
            lines.append([dim, fmt(alpha, "g"), n, rule, fmt(first.get("L2")), fmt(last.get("L2")), fmt(ratio, ".1e"),
                          fmt(fit, ".2f"), fmt(last.get("penetration"), ".2e"),
                          sum(not r["converged"] for r in rows), fmt(tends)])
    return table(header, lines), verdict


def limit_section(found):
    summary, verdict = limit_summary(found)
    said = [f"`{rule}`: " + ("tends to u_S,h in every case" if all(v) else
                             f"tends to u_S,h in {sum(v)} of {len(v)} cases") for rule, v in verdict.items()]
    return "\n".join([
        "## The limit ε → 0: which rule tends to the discrete Signorini solution", "",
        "u_{S,h}, the discrete Signorini solution with the nodal constraint u_h ≤ 0 at the Γ_C vertices, is "
        "solved directly as a variational inequality (`signorini_cli/problems/vi.py`, PETSc's vinewtonrsls), and each rule's "
        "u_{ε,h} on the same mesh is measured against it down ε = 1e-2 … 1e-14 (`study_type: epsilon_sweep`; "
        f"2-D: `{LIMIT_2D.relative_to(ROOT)}` on N = {LIMIT_LEVELS[2]}, 3-D: f = 10 sin(2πx), u = 0 on Γ_D, on "
        f"N = {LIMIT_LEVELS[3]}). 'fitted slope': of log(L2 difference) against log ε over the smallest ε; "
        f"'tends to u_S,h': that slope is at least {TENDS_SLOPE:g} (the difference still falls; the proof of the "
        "paper's Lemma 2.5 gives ε^{1/(α+1)} for the penetration) and the last solve converged; a rule whose limit "
        "is another function stalls there at a slope near 0.", "",
        summary, "", "; ".join(said) + ".", "",
        "What each rule can tend to: as ε → 0 the penalty forces [u_h]_+ = 0 where the rule looks. For P1, "
        "u_h ≤ 0 on a whole facet is u_h ≤ 0 at its vertices, so the exact rule and the vertex rule both impose "
        "the nodal constraint of u_{S,h}. A Gauss rule looks only at its interior points: u_h ≤ 0 there is a "
        "weaker constraint, which still lets a vertex next to the free boundary penetrate; its limit is u_{S,h} "
        "only where that does not pay, and the table shows whether it does (a slope near 0 and a penetration "
        "that stays positive)."])


# --- the page ---------------------------------------------------------------------------------------

def done_when(cases):
    """Whether every stiff study converged on every level up to the issue's reach."""
    reach = {2: 256, 3: 32}
    lines = []
    for path, cfg, (_, rows), _, _ in cases:
        finest = max(r["N"] for r in rows)
        ok = all(r["converged"] for r in rows) and finest >= reach[cfg.dimension]
        lines.append([path.stem, f"{cfg.dimension}-D", finest, fmt(ok)])
    return "\n".join(["## Done when", "", table(["case", "d", "finest N",
                                              "every level converged up to N = 256 (2-D) / 32 (3-D)"], lines)])


def header(out):
    cpu = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                if line.startswith("model name")), platform.processor()) if Path("/proc/cpuinfo").exists() else ""
    return "\n".join(["# Stability on stiff and extreme cases", "",
                      provenance.line("stiff", sorted({p.parent for p in Path(out).rglob("study.h5")})), "",
                      f"`scripts/stability.py` on {cpu}, {os.cpu_count()} cores, 1 MPI rank.", "",
                      "How a level is solved and when it counts as converged: docs/guide/solvers.md. In short: "
                      "`strategy: auto` starts each level from the previous level's solution (nested iteration) and "
                      "falls back to ε-continuation when Newton fails; a solve succeeds when ‖F‖ ≤ rtol · "
                      "‖load without penalty‖, or when the full Newton correction is ≤ stol · ‖u_h‖ (directly, "
                      "or predicted by the quadratic model and confirmed by a simplified Newton correction); then up to "
                      "`solver.polish` more Newton steps bring the predicted error below 1e-13 ‖u_h‖ (or to the "
                      "round-off floor), so that the algebraic error of every reported error stays below 1e-6 of it "
                      "(`make precision`)."])


SECTIONS = ("stiff", "regular", "delta", "condition", "rules", "limit")


def sections(name, out):
    """The page's sections `name` stands for, from its runs into `out`."""
    if name == "stiff":
        cases = stiff_suite(out / "stiff")
        return [done_when(cases), stiff_section(cases)]
    return [{"regular": lambda: regular_section(*regular_studies(out / "regular")),
             "delta": lambda: delta_section(delta_sweep(out / "delta")),
             "condition": lambda: condition_section(*condition_sweep(out / "condition")),
             "rules": lambda: rules_section(rule_runs(out / "rules")),
             "limit": lambda: limit_section(limit_runs(out / "limit"))}[name]()]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", default=str(ROOT / "results" / "stability"), help="where the runs go")
    parser.add_argument("--page", default=str(ROOT / "docs" / "stability.md"), help="the page to write")
    parser.add_argument("--reuse", action="store_true",
                        help="read earlier runs with the same config instead of running them (page changes only)")
    parser.add_argument("--sections", nargs="+", choices=SECTIONS, default=SECTIONS,
                        help="the sections to make (default: all; a partial page is for trying the generator)")
    args = parser.parse_args(argv)
    out = Runs(Path(args.output), args.reuse)
    body, seconds = [], {}
    for name in args.sections:
        start = time.perf_counter()
        body += sections(name, out)
        seconds[name] = time.perf_counter() - start
        print(f"{name}: {seconds[name]:.0f} s", file=sys.stderr, flush=True)
    timing = table(["section", "seconds"], [[name, f"{t:.0f}"] for name, t in seconds.items()])
    page = [header(args.output)] + body + ["## Cost of this page\n\n" + timing]
    Path(args.page).parent.mkdir(parents=True, exist_ok=True)
    Path(args.page).write_text("\n\n".join(page) + "\n")
    print(f"wrote {args.page}")


if __name__ == "__main__":
    main()
