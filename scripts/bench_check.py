"""`make bench-check`: the short part of `make bench` (start-up, the whole default run against the tutorial-style
script, the finest 2-D level's checks and memory), its targets checked against the last full bench's numbers
(bench/targets.json): fails when a target regresses. `make bench` runs the same pieces (with more repeats and the
labelled LU-from-zero and nested scripts) and writes its table of targets from them and from its studies.

Whole processes are timed as /usr/bin/time does (wall clock; user + system CPU and peak resident set of the child
from os.wait4), each the median of several runs taken in turn (A B C A B C ...), so that a slow spell of this
shared machine falls on every command alike. The processes compile and cache their bytecode as a user's
installation has it (PYTHONPYCACHEPREFIX under results/bench/), whatever the calling environment says."""
import csv
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
RUNS = ROOT / "results" / "bench"
BASELINE = ROOT / "bench" / "targets.json"  # the last full bench's measured targets
PYTHON = sys.executable
SIGNORINI = str(Path(PYTHON).parent / "signorini")  # the console script, as a user calls it
DEMO_LEVELS = "[8, 16, 32, 64, 128, 256, 512]"
TUTORIAL = [PYTHON, "scripts/tutorial_baseline.py"]
# the whole default run (figures included) and the tutorial-style scripts on the same levels, fresh processes;
# `tutorial` (SNES Newton from zero, CG + BoomerAMG, the positive part by ufl.conditional) is the reference
WHOLE_RUNS = {"signorini": [SIGNORINI, "run", "configs/demo.yaml", "--force", "--quiet", "--output",
                            str(RUNS / "whole"), "--set", f"mesh.refinements={DEMO_LEVELS}"],
              "tutorial": TUTORIAL,
              "tutorial-lu": TUTORIAL + ["--solver", "lu"],
              "tutorial-nested": TUTORIAL + ["--nested"]}
SHORT_WHOLE_RUNS = ("signorini", "tutorial")
STARTUP = {"python": [PYTHON, "-c", "pass"], "version": [SIGNORINI, "--version"],
           "check": [SIGNORINI, "check", "configs/demo.yaml"],
           "imports": [PYTHON, "-c", "import signorini_cli.app.commands"]}  # the modules every run loads
# --resume extending a finished study by one level against a fresh run of all its levels (figures included)
RESUME_LEVELS = ("[64, 128, 256, 512]", "[64, 128, 256, 512, 1024]")
RESUME_FOLDERS = {name: RUNS / "resume" / name for name in ("finished", "fresh", "resume")}
FINEST = ROOT / "bench" / "configs" / "square.yaml"
FINEST_LEVELS = "[512, 1024]"  # the finest 2-D level after the one it starts from (nested iteration)
# (key, what, limit, sense): the speed contract, in the order of the page's table
TARGETS = (("whole_over_tutorial", "whole default run N = 8..512 / the tutorial-style script (SNES Newton from "
            "zero, CG + AMG), median of 5", 0.35, "<="),
           ("kb_per_dof", "finest 2-D level N = 1024: peak memory per dof (kB), serial, no floor measured", 0.7, "<="),
           ("floor_ratio", "finest 2-D level: level time / its linear floor", 2.0, "<="),
           ("study_over_floors_square", "whole study / sum of linear floors, square", 2.5, "<="),
           ("study_over_floors_cube", "whole study / sum of linear floors, cube", 2.5, "<="),
           ("study_over_floors_stiff", "whole study / sum of linear floors, stiff", 2.5, "<="),
           ("checks_share", "residual check + data check, share of the finest 2-D level's time", 0.05, "<="),
           ("version_over_python", "`signorini --version` / `python -c pass`", 3.0, "<="),
           ("cube_128_two_ranks_s", "3-D 128^3 level on 2 ranks (s)", 40.0, "<="),
           ("speedup", "2-rank speed-up of the finest 2-D level", 1.7, ">="),
           ("elastic_3d_floor_ratio", "3-D elastic Newton / linear floor at 32^3", 1.5, "<="),
           ("resume_over_fresh", "`--resume` extending N = 64..512 by 1024 / a fresh run of N = 64..1024, median of 5",
            0.7, "<="))
# how much worse than the last full bench a measured value may be before a target counts as regressed (a
# target that is met never regresses): this machine's whole-process times vary by ~10 % between spells
NOISE = 0.15


def environment():
    """The processes' environment: MPI as root, and bytecode compiled once and cached, as installed."""
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", PYTHONPYCACHEPREFIX=str(RUNS / "pycache"))
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def timed_process(command):
    """{wall_s, cpu_s, peak_mb} of one fresh process (its output discarded); a failed one raises."""
    start = time.perf_counter()
    child = subprocess.Popen(command, cwd=ROOT, env=environment(), stdout=subprocess.DEVNULL)
    _, status, usage = os.wait4(child.pid, 0)
    wall = time.perf_counter() - start
    child.returncode = os.waitstatus_to_exitcode(status)
    if child.returncode != 0:
        raise subprocess.CalledProcessError(child.returncode, command)
    return {"wall_s": wall, "cpu_s": usage.ru_utime + usage.ru_stime, "peak_mb": usage.ru_maxrss / 1024}


def alternating(commands, repeats):
    """Each of `commands` ({name: argv}) `repeats` times in turn; per name the median of each measure and the
    walls of every run."""
    found = {name: [] for name in commands}
    for k in range(repeats):
        for name, command in commands.items():
            print(f"== {name} ({k + 1}/{repeats}): {' '.join(command)}", flush=True)
            found[name].append(timed_process(command))
    return medians(found)


def medians(found):
    """Per name of `found` ({name: [timed_process results]}) the median of each measure and the walls of every run."""
    return {name: dict({key: float(np.median([r[key] for r in runs])) for key in runs[0]},
                       walls=[r["wall_s"] for r in runs]) for name, runs in found.items()}


def startup(repeats=5):
    """The start-up commands, after one untimed run each (the bytecode cache filled)."""
    for command in STARTUP.values():
        timed_process(command)
    return alternating(STARTUP, repeats)


def whole_runs(names, repeats):
    """The whole default run and the tutorial-style scripts `names`, `repeats` times in turn."""
    return alternating({name: WHOLE_RUNS[name] for name in names}, repeats)


def demo_run(folder, levels, *flags):
    """`signorini run configs/demo.yaml` on `levels` into `folder`."""
    return [SIGNORINI, "run", "configs/demo.yaml", "--quiet", *flags, "--output", str(folder), "--set",
            f"mesh.refinements={levels}"]


def resume_runs(repeats=3):
    """--resume extending the finished demo study on N = 64..512 by N = 1024 against a fresh run on N = 64..1024,
    `repeats` times in turn (the finished study copied afresh before each resume, untimed): the medians as
    `alternating` gives them, and each run's level times (time_s of its rates.csv)."""
    finished, fresh, resumed = RESUME_FOLDERS.values()
    timed_process(demo_run(finished, RESUME_LEVELS[0], "--force"))
    found = {"fresh": [], "resume": []}
    for k in range(repeats):
        print(f"== fresh and --resume ({k + 1}/{repeats})", flush=True)
        found["fresh"].append(timed_process(demo_run(fresh, RESUME_LEVELS[1], "--force")))
        shutil.rmtree(resumed, ignore_errors=True)
        shutil.copytree(finished, resumed)
        found["resume"].append(timed_process(demo_run(resumed, RESUME_LEVELS[1], "--resume")))
    summary = medians(found)
    for name, folder in (("fresh", fresh), ("resume", resumed)):
        summary[name]["level_s"] = level_times(folder)
    return summary


def level_times(folder):
    """time_s of every level in the study's rates.csv under `folder` (the last run's)."""
    with open(next(Path(folder).glob("*/rates.csv"))) as f:
        return [float(row["time_s"]) for row in csv.DictReader(f)]


def finest_level():
    """The finest 2-D level of the square study (N = 1024 after 512, no floor), in a fresh process: its wall
    time, peak memory per dof and the seconds its residual check and data check took (measure_checks)."""
    out = RUNS / "finest.json"
    subprocess.run([PYTHON, "scripts/bench_check.py", "--measure-checks", str(out)], cwd=ROOT, env=environment(),
                   check=True)
    return json.loads(out.read_text())


def measure_checks(out):
    """In this process: the square study on FINEST_LEVELS with strategies.checked and registry.check_posed
    timed (their module attributes wrapped), the finest level's share of them written to `out`."""
    from signorini_cli import config, studies
    from signorini_cli.problems import registry
    from signorini_cli.solve import strategies
    spent = {"checked": 0.0, "check_posed": 0.0}
    for module, name in ((strategies, "checked"), (registry, "check_posed")):
        setattr(module, name, _timed(getattr(module, name), spent, name))
    before = []
    cfg = config.load(FINEST, overrides=[f"mesh.refinements={FINEST_LEVELS}", "solver.linear_floor=false"])
    levels = studies.run_study(cfg, on_level=lambda levels: before.append(dict(spent)))
    finest = levels[-1]
    checks = {name: spent[name] - before[-2][name] for name in spent}
    kb_per_dof = finest.timings["peak_memory_mb"] * 2**20 / 1000 / finest.dofs
    Path(out).write_text(json.dumps(dict(checks, time_s=finest.time_s, dofs=finest.dofs, kb_per_dof=kb_per_dof,
                                         converged=finest.outcome.converged)))


def _timed(function, spent, name):
    def timed(*args, **kwargs):
        start = time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            spent[name] += time.perf_counter() - start
    return timed


def short_measures(whole):
    """The targets the short part measures: {key: value}, from `whole` (whole_runs), start-up and the finest
    level; with the raw measurements under 'raw'."""
    start, finest = startup(), finest_level()
    values = {"whole_over_tutorial": whole["signorini"]["wall_s"] / whole["tutorial"]["wall_s"],
              "version_over_python": start["version"]["wall_s"] / start["python"]["wall_s"],
              "checks_share": (finest["checked"] + finest["check_posed"]) / finest["time_s"],
              "kb_per_dof": finest["kb_per_dof"]}
    return dict(values, raw={"whole": whole, "startup": start, "finest": finest})


def rows(values):
    """(key, what, measured or None, limit, sense, met) for every target."""
    found = []
    for key, what, limit, sense in TARGETS:
        value = values.get(key)
        met = value is not None and (value <= limit if sense == "<=" else value >= limit)
        found.append((key, what, value, limit, sense, met))
    return found


def regressions(values, baseline):
    """The targets among `values` that regressed: missed now, and met in `baseline` (the last full bench's values)
    or worse than it by more than NOISE; without a baseline value, every missed target."""
    regressed = []
    for key, what, value, limit, sense, met in rows(values):
        if value is None or met:
            continue
        before = baseline.get(key)
        worse = before is None or (value > before * (1 + NOISE) if sense == "<=" else value < before * (1 - NOISE))
        was_met = before is not None and (before <= limit if sense == "<=" else before >= limit)
        if worse or was_met:
            regressed.append((key, what, value, before, limit, sense))
    return regressed


def table(values):
    """The Markdown table of targets: measured, target, met (— where this run measured none)."""
    lines = ["| target | measured | target | met |", "|---|---|---|---|"]
    for _, what, value, limit, sense, met in rows(values):
        measured = "–" if value is None else f"{value:.3g}"
        verdict = "–" if value is None else "yes" if met else "**no**"
        lines.append(f"| {what} | {measured} | {sense} {limit} | {verdict} |")
    return lines


def main(argv=None):
    """bench-check: the short part, its table, and exit 1 when a target regressed against bench/targets.json."""
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--measure-checks"]:
        measure_checks(argv[1])
        return 0
    started = time.perf_counter()
    values = short_measures(whole_runs(SHORT_WHOLE_RUNS, repeats=3))
    baseline = json.loads(BASELINE.read_text()) if BASELINE.exists() else {}
    print("\n".join(table(values)))
    raw = values.pop("raw")
    print(f"whole runs (median wall s): " + ", ".join(f"{k} {v['wall_s']:.2f}" for k, v in raw["whole"].items()))
    print(f"start-up (median wall s): " + ", ".join(f"{k} {v['wall_s']:.3f}" for k, v in raw["startup"].items()))
    print(f"finest level: {raw['finest']}")
    regressed = regressions(values, baseline)
    for key, what, value, before, limit, sense in regressed:
        print(f"REGRESSED: {what}: {value:.3g} (last full bench: {before if before is None else f'{before:.3g}'}; "
              f"target {sense} {limit})")
    print(f"bench-check took {time.perf_counter() - started:.0f} s; "
          + ("no target regressed" if not regressed else f"{len(regressed)} target(s) regressed"))
    return 1 if regressed else 0


if __name__ == "__main__":
    sys.exit(main())
