"""docs/methods.md from the runs of configs/methods/ (`make methods`): Nitsche's method against the penalty
(compliance) model on the same manufactured Signorini solution u_S, at equal N and equal run time.

    python scripts/methods_page.py CONFIG.yaml ... [--output RESULTS] [--out docs/methods.md]
reads each config's results (refinement studies of either method, and a map over problem.method) and writes
the page; every number on the page comes from those results."""
import argparse
import math
import sys
from pathlib import Path

import numpy as np

import cells
import provenance
from signorini_cli import config
from signorini_cli.analysis import rates
from signorini_cli.record import csvfile, results

FIT = 3  # levels in each fitted rate, as the studies' verdicts
NORM = "H1"  # the norm Nitsche's rate is proven in


def main(argv=None):
    parser = argparse.ArgumentParser(prog="scripts/methods_page.py", description=__doc__.split("\n")[0])
    parser.add_argument("configs", nargs="+", help="the configs/methods studies, already run")
    parser.add_argument("--output", help="the results folder the studies were run with (overrides output.dir)")
    parser.add_argument("--out", default="docs/methods.md", help="the page to write")
    args = parser.parse_args(argv)
    runs, maps = [], []
    for path in args.configs:
        cfg = config.load(path, [f"output.dir={args.output}"] if args.output else [])
        if cfg.study_type == "map":  # its points' table: map.csv
            maps.append((path, cfg))
        else:
            runs.append(Run(path, cfg, results.load(cfg.output_dir).rows))
    made_from = provenance.line("methods", [run.cfg.output_dir for run in runs])
    nitsche = [run for run in runs if run.cfg.problem.method == "nitsche"]
    penalty = [run for run in runs if run.cfg.problem.method != "nitsche"]
    sections = [HEADER.replace("{provenance}", made_from), equal_n(runs), verdicts(nitsche),
                equal_time(nitsche, penalty, maps), *[map_section(*m) for m in maps], answer(nitsche, penalty)]
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n\n".join(sections) + "\n")
    print(f"wrote {out}")
    return 0


class Run:
    """One study of the page: its config path, Config and rate-table rows (read through record/)."""

    def __init__(self, path, cfg, rows):
        self.path, self.cfg, self.rows = path, cfg, rows
        self.ok = [bool(r["converged"]) for r in rows]
        self.h = [r["h"] for r in rows]
        self.errors = [r.get(NORM) for r in rows]
        self.seconds = list(np.cumsum([r["time_s"] or 0.0 for r in rows]))  # the study's time up to each level
        self.fit = rates.fit(self.h, self.errors, self.ok, FIT)

    @property
    def label(self):
        if self.cfg.problem.method == "nitsche":
            return f"Nitsche θ = {self.cfg.nitsche.theta:g}, γ0 = {self.cfg.nitsche.gamma0:g}"
        return f"penalty α = {self.cfg.alpha:g}, ε = {self.cfg.epsilon.formula()}"

    def rate(self):
        return "–" if self.fit is None else f"{self.fit.slope:.2f} [{self.fit.lo:.2f}, {self.fit.hi:.2f}]"


HEADER = """# Nitsche's method beside the penalty model: the same Signorini problem, the same meshes and norms

{provenance} Runs of `configs/methods/*.yaml`.
All studies solve the Signorini problem −Δu = f, u ≤ 0, ∂_n u ≤ 0, u ∂_n u = 0 on Γ_C with the manufactured
solution u_S of [signorini-solution.md](signorini-solution.md) (P1, unit square, Γ_C the bottom face):
Nitsche's method (`problem.method: nitsche`, γ = γ0 h_K; Chouly & Hild 2013, Chouly, Hild & Renard 2015)
discretises it consistently, the penalty model (`problem.method: penalty`, ε = θh^p) solves the compliance
problem instead, so its error against u_S is a total error (discretisation + model error O(ε^{1/α}), see
[limit.md](limit.md)). `H1` = |u_S − u_h|_{H¹(Ω)} (seminorm); rates are least-squares slopes over the last
3 levels with their ± 2 standard-error intervals; time is the study's cumulative wall time up to the level.
Side by side as figures: `signorini compare <output>/methods-nitsche-theta1 <output>/methods-penalty-alpha1-p1`."""


def equal_n(runs):
    """H1 of every study at each N, and the fitted rate."""
    ns = sorted({r["N"] for run in runs for r in run.rows})
    head = "| study | " + " | ".join(f"N = {n}" for n in ns) + " | H1 rate (fit) | time (s) |"
    lines = [head, "|" + "---|" * (len(ns) + 3)]
    for run in runs:
        by_n = {r["N"]: r for r in run.rows}
        cells_ = [f"{by_n[n][NORM]:.3e}" if n in by_n and by_n[n]["converged"] else "–" for n in ns]
        lines.append(f"| {run.label} | " + " | ".join(cells_) + f" | {run.rate()} | {run.seconds[-1]:.2f} |")
    return "\n".join(["## 1. Equal N: the H1 error on each mesh", "", *lines])


def verdicts(nitsche):
    """Each Nitsche study's verdict against the proven H1 rate (its summary.csv)."""
    lines = ["| study | observed | interval | proven | verdict | why |", "|---|---|---|---|---|---|"]
    for run in nitsche:
        for row in csvfile.read(run.cfg.output_dir / "summary.csv"):
            if row.get("kind") == "norm" and row.get("name") == NORM:
                lines.append(f"| {run.label} | {cells.rate(row['observed_rate'])} | [{cells.rate(row['rate_lo'])}, "
                             f"{cells.rate(row['rate_hi'])}] | {cells.rate(row['proven_rate'])} | {row['verdict']} "
                             f"| {row['reason']}; {row['conditions']} |")
    return "\n".join(["## 2. Nitsche's verdicts against the proven rate", "",
                      "Proven: |u − u_h|_H1 = O(h^{1/2+ν}) for u ∈ H^{3/2+ν}; u_S ∈ H² gives O(h) for P1. θ = −1 "
                      "holds for any γ0 > 0; θ = 1 and 0 need γ0 below a bound the study does not compute, so a "
                      "rate below 1 would be `inconclusive` there.", "", *lines])


def at_time(run, seconds):
    """The study's H1 error at a cumulative time, interpolated log-log between its levels (None outside)."""
    t = [s for s, ok in zip(run.seconds, run.ok) if ok]
    e = [err for err, ok in zip(run.errors, run.ok) if ok]
    if not t or not t[0] <= seconds <= t[-1]:
        return None
    return float(math.exp(np.interp(math.log(seconds), np.log(t), np.log(e))))


def noise(reference, maps):
    """How much one study's time varies between runs: the reference run against the same point of a map."""
    for _, cfg in maps:
        for row in csvfile.read(cfg.output_dir / "map.csv"):
            same = (row.get("problem.method") == "nitsche" and row.get("nitsche.theta") == reference.cfg.nitsche.theta
                    and row.get("nitsche.gamma0") == reference.cfg.nitsche.gamma0)
            levels = len(cfg.mesh.levels)
            if same and levels <= len(reference.seconds):
                own = reference.seconds[levels - 1]
                return (f"Times are of a machine shared with other work: the same study (N = {cfg.mesh.levels[0]} to "
                        f"{cfg.mesh.levels[-1]}) took {own:.2f} s here and {row['time_s']:.2f} s as a point of the "
                        "map below; differences within that ratio say nothing.")
    return ""


def equal_time(nitsche, penalty, maps):
    """Each penalty study's error at the times Nitsche θ = 1 reached its levels, as a ratio to Nitsche's."""
    reference = next((run for run in nitsche if run.cfg.nitsche.theta == 1), None)
    if reference is None:
        return "## 3. Equal run time\n\n(no Nitsche θ = 1 study)"
    lines = ["| study | " + " | ".join(f"t = {t:.2f} s (N = {r['N']})" for t, r in zip(reference.seconds,
                                                                                  reference.rows)) + " |",
             "|" + "---|" * (len(reference.rows) + 1)]
    for run in [reference] + [r for r in nitsche if r is not reference] + penalty:
        values = [at_time(run, t) for t in reference.seconds]
        lines.append(f"| {run.label} | " + " | ".join("–" if v is None else f"{v:.3e}" for v in values) + " |")
    return "\n".join(["## 3. Equal run time: the H1 error each study had reached at the same wall time", "",
                      f"Reference times: {reference.label}'s cumulative times at its levels; other studies' errors "
                      "interpolated log-log between their own levels (– outside their range). " + noise(reference, maps),
                      "", *lines])


def map_section(path, cfg):
    """The map over problem.method (and θ, γ0): its map.csv."""
    rows = csvfile.read(cfg.output_dir / "map.csv")
    keys = [k for k in rows[0] if not k.startswith(("rate_", "proven_", "verdict_", "L2", "H1"))
            and k not in ("converged", "newton_its", "time_s", "status")] if rows else []
    lines = ["| " + " | ".join(keys) + " | H1 rate [interval] | verdict | finest H1 | its | time (s) |",
             "|" + "---|" * (len(keys) + 5)]
    for row in rows:
        interval = f"{cells.rate(row.get('rate_H1'))} [{cells.rate(row.get('rate_H1_lo'))}, " \
                   f"{cells.rate(row.get('rate_H1_hi'))}]"
        finest = row.get("H1")
        lines.append("| " + " | ".join("–" if row.get(k) is None else str(row[k]) for k in keys) + f" | {interval} | "
                     f"{row.get('verdict_H1', '')} | {'–' if finest is None else f'{finest:.3e}'} | "
                     f"{row.get('newton_its')} | {row.get('time_s', 0.0):.2f} |")
    return "\n".join([f"## 4. The map over problem.method, θ and γ0 (`{path}`)", "", *lines])


def answer(nitsche, penalty):
    """Does the penalty's total error fall at Nitsche's rate? Per penalty study, from the fitted intervals."""
    best = max((run for run in nitsche if run.fit is not None), key=lambda run: run.fit.slope, default=None)
    if best is None or not penalty:
        return "## 5. Answer\n\n(not enough converged studies)"
    lines = []
    for run in penalty:
        if run.fit is None:
            lines.append(f"- {run.label}: no fitted rate.")
            continue
        same = run.fit.lo <= best.fit.hi and best.fit.lo <= run.fit.hi
        finest = {r["N"]: r[NORM] for r in run.rows if r["converged"]}
        n = max(set(finest) & {r["N"] for r in best.rows})
        ratio = finest[n] / next(r[NORM] for r in best.rows if r["N"] == n)
        lines.append(f"- {run.label}: H1 rate {run.rate()} against {best.label}'s {best.rate()}: "
                     f"{'yes, the intervals overlap' if same else 'no, the intervals are apart'}; at N = {n} "
                     f"its error is {ratio:.2f} times Nitsche's.")
    return "\n".join(["## 5. Does the penalty's total error fall at Nitsche's rate on this problem?", "", *lines])


if __name__ == "__main__":
    sys.exit(main())
