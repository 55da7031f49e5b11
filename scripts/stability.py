"""`make stiff`: run the stiff suite, the regular studies, a smoothing (delta) sweep and a conditioning
sweep, and write docs/stability.md from the runs. Every number in that page comes from here."""
import argparse
import csv
import dataclasses
import datetime
import io
import math
import os
import platform
import re
from contextlib import redirect_stdout
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from signorini_cli import cli, config

ROOT = Path(__file__).resolve().parent.parent
EASY_ITS = 3  # the target: at most 3 Newton iterations after the first level with strategy auto
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
    """Run one study through the command line (in this process) into the Runs `out`; return
    (exit status, rows)."""
    cfg = config.load(path, list(overrides) + [f"output.dir={out.root}"])
    status = reused(cfg) if out.reuse else None
    if status is None:
        args = ["run", str(path), "--output", str(out.root), "--force", "--quiet"]
        for item in overrides:
            args += ["--set", item]
        with redirect_stdout(io.StringIO()):
            status = cli.main(args)
    if status >= 128:  # interrupted (SIGINT, SIGTERM): the page would be half made, stop here
        raise SystemExit(status)
    with open(cfg.output_dir / "rates.csv") as f:
        return status, [_typed(row) for row in csv.DictReader(f)]


def reused(cfg):
    """The exit status of a finished earlier run of exactly this config (same hash), or None. Only for
    reworking the page: the hash does not see changes to the code."""
    import h5py
    path = cfg.output_dir / "study.h5"
    if not path.exists():
        return None
    with h5py.File(path, "r") as h5:
        if h5.attrs.get("config_hash") != config.fingerprint(cfg) or h5.attrs.get("status") != "complete":
            return None
        return 0 if all(h5["table/converged"][()]) else 1


def _typed(row):
    out = {}
    for key, value in row.items():
        if value in ("true", "false"):
            out[key] = value == "true"
        elif value == "":
            out[key] = None
        else:
            try:
                out[key] = int(value) if value.lstrip("-").isdigit() else float(value)
            except ValueError:
                out[key] = value
    return out


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
    pairs = [(a, b) for a, b in zip(x, y) if a and b]
    return float(np.polyfit(np.log([a for a, _ in pairs]), np.log([b for _, b in pairs]), 1)[0]) if len(pairs) > 1 else None


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


def header():
    cpu = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                if line.startswith("model name")), platform.processor()) if Path("/proc/cpuinfo").exists() else ""
    return "\n".join(["# Stability on stiff and extreme cases", "",
                      f"Generated by `make stiff` (`scripts/stability.py`) on {datetime.date.today()}, "
                      f"{cpu}, {os.cpu_count()} cores, 1 MPI rank. Do not edit by hand.", "",
                      "How a level is solved and when it counts as converged: README.md, *Robust solves*. In short: "
                      "`strategy: auto` starts each level from the previous level's solution (nested iteration) and "
                      "falls back to ε-continuation when Newton fails; a solve converges when ‖F‖ ≤ rtol · ‖load "
                      "without penalty‖, or when the full Newton correction is ≤ stol · ‖u_h‖ (directly, or predicted "
                      "by the quadratic model and confirmed by a simplified Newton correction)."])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", default=str(ROOT / "results" / "stability"), help="where the runs go")
    parser.add_argument("--page", default=str(ROOT / "docs" / "stability.md"), help="the page to write")
    parser.add_argument("--reuse", action="store_true",
                        help="read earlier runs with the same config instead of running them (page changes only)")
    args = parser.parse_args(argv)
    out = Runs(Path(args.output), args.reuse)
    cases = stiff_suite(out / "stiff")
    sections = [header(), done_when(cases), stiff_section(cases),
                regular_section(*regular_studies(out / "regular")), delta_section(delta_sweep(out / "delta")),
                condition_section(*condition_sweep(out / "condition"))]
    Path(args.page).parent.mkdir(parents=True, exist_ok=True)
    Path(args.page).write_text("\n\n".join(sections) + "\n")
    print(f"wrote {args.page}")


if __name__ == "__main__":
    main()
