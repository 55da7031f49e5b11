"""`make precision`: every shipped config solved at default settings and with a tight solve, every error
column of every table compared (the default keeps each within 1e-6 of the tight one),
and the cost of the default's polish (Newton steps after success) against `solver.polish=0`."""
import argparse
import math
import sys
import time
from pathlib import Path

import yaml

import provenance
import signorini_cli
from signorini_cli import config
from signorini_cli.analysis import rates
from signorini_cli.record import csvfile
from signorini_cli.solve import solver

ROOT = Path(__file__).resolve().parent.parent
AGREE = 1e-6  # the bound: the algebraic error of a reported quantity <= 1e-6 of it
# an entry below 1e-12 of its row's largest error entry is round-off of a quantity zero in exact arithmetic
# ([u]_+ − [u_h]_+ where u = 0 on Γ_C: 1e-18 against 3e-34 on the L-shape corner case); the solve's own
# precision, ~1e-13 of the solution, leaves no significant digit there to compare
ROUND_OFF = 1e-12
# the tight solve: after success always 3 more Newton steps, the polish's own stopping rule switched off
# (SuccessTest.polished never true, unless a step is exactly 0). A correction bounded by test (S) and squared
# at each step reaches round-off; where round-off floors the steps (α = 2, ε = 1e-8), a stricter success
# test (stol = 1e-12) cannot pass at all. A step that fails returns the last iterate that passed.
TIGHT = (("solver.polish=3",), {"POLISH_TOL": 0.0, "POLISH_STALL": math.inf})
UNPOLISHED = (("solver.polish=0",), {})  # the former default, without the polish: the cost baseline
# coarse levels keep `make precision` near 20 minutes on 2 cores: the first levels of each family
MAX_LEVELS = {2: 4, 3: 3}
VARIANTS = {"default": ((), {}), "tight": TIGHT, "unpolished": UNPOLISHED}


def coarse(path):
    """The --set overrides that keep a config's first MAX_LEVELS levels (none when it has no more)."""
    raw = yaml.safe_load(Path(path).read_text())
    mesh, dim = raw.get("mesh", {}), raw.get("dimension", 2)
    keep = MAX_LEVELS[3 if mesh.get("kind") == "unit_cube" or dim == 3 else 2]
    for key in ("refinements", "sizes"):
        if isinstance(mesh.get(key), list) and len(mesh[key]) > keep:
            return (f"mesh.{key}={mesh[key][:keep]}",)
    return ()


def run(path, out, overrides, variant):
    """One study through the API, in this process, as VARIANTS[variant] says, its record written as `signorini
    run` writes it; (exit status as `signorini run` gives it: 0, or 1 when a solve did not converge, wall
    seconds, tables)."""
    extra, constants = VARIANTS[variant]
    cfg = config.load(path, [*overrides, *extra, f"output.dir={out}"])
    saved = {name: getattr(solver, name) for name in constants}
    start = time.perf_counter()
    try:
        for name, value in constants.items():
            setattr(solver, name, value)
        study = signorini_cli.run(cfg, write=True)
    finally:
        for name, value in saved.items():
            setattr(solver, name, value)
    return int(not (study.converged and study.met)), time.perf_counter() - start, read_tables(out)


def read_tables(out):
    """Every CSV table the run wrote, keyed by its path below `out`: rows of dicts of numbers or text."""
    tables = {}
    for path in sorted(Path(out).rglob("*.csv")):
        tables[str(path.relative_to(out))] = csvfile.read(path)
    return tables


def deviations(default, tight):
    """(table, row, column, default value, tight value, relative difference) of every error entry."""
    found = []
    for name, rows in tight.items():
        for i, (a, b) in enumerate(zip(default.get(name, []), rows)):
            columns = rates.error_columns(rows)
            floor = ROUND_OFF * max((abs(b[c]) for c in columns if isinstance(b.get(c), float)
                                     and math.isfinite(b[c])), default=0.0)
            for column in columns:
                x, y = a.get(column), b.get(column)
                if isinstance(x, float) and isinstance(y, float) and not (math.isnan(x) and math.isnan(y)):
                    found.append((name, i, column, x, y, relative(x, y, floor)))
    return found


def relative(x, y, floor=0.0):
    """|x − y| / |y|; 0 where both lie at or below `floor` (round-off: no digit of either is significant)."""
    if max(abs(x), abs(y)) <= floor:
        return 0.0
    if y == 0.0:
        return 0.0 if x == 0.0 else math.inf
    return abs(x - y) / abs(y)


def unconverged(tables):
    """How many rows of the run's tables say converged = false."""
    return sum(row.get("converged") is False for rows in tables.values() for row in rows)


def newton_its(tables):
    """Newton iterations over the run's level tables (rates.csv and the ε-sweep's points)."""
    return int(sum(row.get("newton_its") or 0 for name, rows in tables.items()
                   if Path(name).name in ("rates.csv", "sweep.csv") for row in rows))


def check(path, out):
    """Run one config in every variant; the facts for its line of the summary."""
    overrides = coarse(path)
    runs = {name: run(path, out / name, overrides, name) for name in VARIANTS}
    found = deviations(runs["default"][2], runs["tight"][2])
    worst = max(found, key=lambda d: d[5], default=None)
    return {"config": str(path.relative_to(ROOT)), "levels": overrides[0].split("=", 1)[1] if overrides else "all",
            "entries": len(found), "worst": worst, "unpolished_worst": max(
                (d[5] for d in deviations(runs["unpolished"][2], runs["tight"][2])), default=None),
            "unconverged": {k: unconverged(r[2]) for k, r in runs.items()},
            "its": {k: newton_its(r[2]) for k, r in runs.items()}, "seconds": {k: r[1] for k, r in runs.items()}}


def summary(lines):
    """The markdown table of the checks and its verdict."""
    head = ["config", "levels", "error entries", "largest rel. difference (default vs tight)", "where",
            "same with polish 0", "not converged (default/tight)", "Newton its (polish 0 → default, tight)",
            "seconds (polish 0 → default)"]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for c in lines:
        worst = c["worst"]
        where = f"{worst[0]} row {worst[1]} {worst[2]}" if worst else "–"
        mark = "**" if worst and worst[5] > AGREE else ""
        out.append("| " + " | ".join([
            c["config"], c["levels"], str(c["entries"]), f"{mark}{worst[5]:.1e}{mark}" if worst else "–", where,
            f"{c['unpolished_worst']:.1e}" if c["unpolished_worst"] is not None else "–",
            f"{c['unconverged']['default']}/{c['unconverged']['tight']}",
            f"{c['its']['unpolished']} → {c['its']['default']}, {c['its']['tight']}",
            f"{c['seconds']['unpolished']:.1f} → {c['seconds']['default']:.1f}"]) + " |")
    its = [sum(c["its"][k] for c in lines) for k in ("unpolished", "default")]
    secs = [sum(c["seconds"][k] for c in lines) for k in ("unpolished", "default")]
    bad = [c["config"] for c in lines if c["worst"] and c["worst"][5] > AGREE]
    out += ["", f"Total Newton iterations {its[0]} → {its[1]} (+{its[1] / max(its[0], 1) - 1:.0%}), "
                f"wall time {secs[0]:.0f} s → {secs[1]:.0f} s (+{secs[1] / max(secs[0], 1e-9) - 1:.0%}).",
            f"Every error entry within {AGREE:g} of the tight solve." if not bad else
            f"**Above {AGREE:g}**: {', '.join(bad)}."]
    return "\n".join(out), not bad


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("configs", nargs="*", help="configs to check (default: every configs/**/*.yaml)")
    parser.add_argument("--output", default=str(ROOT / "results" / "precision"), help="where the runs go")
    parser.add_argument("--page", help="also write the generated page here (make precision: docs/precision.md)")
    args = parser.parse_args(argv)
    paths = [Path(p).resolve() for p in args.configs] or sorted(p for p in (ROOT / "configs").rglob("*.yaml")
                                                                if "maps" not in p.parts)  # maps: `make maps`
    lines = []
    for path in paths:
        print(f"== {path.relative_to(ROOT)}", file=sys.stderr, flush=True)
        lines.append(check(path, Path(args.output) / path.relative_to(ROOT / "configs").with_suffix("")))
    text, ok = summary(lines)
    Path(args.output).mkdir(parents=True, exist_ok=True)
    (Path(args.output) / "precision.md").write_text(text + "\n")
    if args.page:
        folders = [folder for folder in Path(args.output).rglob("*") if (folder / "study.h5").exists()]
        Path(args.page).write_text(PAGE.format(provenance=provenance.line("precision", folders), table=text))
        print(f"wrote {args.page}", file=sys.stderr)
    print(text)
    return 0 if ok else 1


PAGE = """# Solved as precisely as it is measured

{provenance} Every shipped config (`configs/**/*.yaml`, its first 4 levels in 2-D and 3 in 3-D) is run three
times: with the default settings, with a tight solve (after success always 3 more Newton steps) and with
`solver.polish: 0` (the stopping test without the polish). For every error entry of every table the relative
difference between the default and the tight solve is listed; the bound is 1e-6 of the quantity. An entry whose
two values both lie below 1e-12 of the largest error entry of its row is round-off of a quantity that is zero in
exact arithmetic (as ‖[u]₊ − [u_h]₊‖ where u = 0 on Γ_C) and counts as agreeing.

{table}
"""


if __name__ == "__main__":
    sys.exit(main())
