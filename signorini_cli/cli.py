"""Command line: `signorini run CONFIG.yaml [--output DIR] [--set KEY=VALUE ...] [--force] [--resume]`;
check, list, report and compare."""
import argparse
import dataclasses
import logging
import sys

import yaml

from . import guard
from .config import ConfigError

EXIT_OK, EXIT_NOT_CONVERGED, EXIT_BAD_INPUT = 0, 1, 2
EXIT_EXPECTATION_NOT_MET = 1  # an `expect:` rate was missed (issue 4)


def build_parser():
    parser = argparse.ArgumentParser(prog="signorini", description=__doc__.split(":")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a convergence study")
    run.add_argument("config", help="study config (YAML)")
    run.add_argument("--output", help="results folder (overrides output.dir)")
    run.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                     help="override a config key, e.g. --set epsilon.theta=10 (repeatable)")
    run.add_argument("--force", action="store_true",
                     help="overwrite existing results of this study; run even when the finest level looks too "
                          "big for the memory")
    run.add_argument("--resume", action="store_true", help="continue an interrupted study from its first "
                                                           "unfinished level (the config must be unchanged)")
    noise = run.add_mutually_exclusive_group()
    noise.add_argument("--quiet", action="store_true", help="print nothing but errors (results still written)")
    noise.add_argument("--verbose", action="store_true", help="also PETSc's SNES and KSP monitors")
    _add_report_commands(sub)
    return parser


def _add_report_commands(sub):
    check = sub.add_parser("check", help="validate a config and print its resolved settings, no solve")
    check.add_argument("config", help="study config (YAML)")
    check.add_argument("--output", help="results folder (overrides output.dir)")
    check.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                       help="override a config key, as for run (repeatable)")
    listing = sub.add_parser("list", help="the shipped configs with their descriptions")
    listing.add_argument("folder", nargs="?", help="a folder of configs (default: the shipped configs/)")
    rep = sub.add_parser("report", help="tables and plots of a finished or partial study, no recomputation")
    rep.add_argument("path", help="a study folder, its study.h5 or its rates.csv")
    rep.add_argument("--digits", type=int, help="digits after the point in rates.md/rates.tex "
                                                "(default: the study's output.digits, else 3)")
    rep.add_argument("--no-plots", action="store_true", help="tables only (matplotlib not imported)")
    rep.add_argument("--output", help="write into this folder instead of the study's")
    compare = sub.add_parser("compare", help="overlay the curves of several studies")
    compare.add_argument("paths", nargs="+", help="study folders (or their study.h5 / rates.csv)")
    compare.add_argument("--label", action="append", metavar="NAME", help="a legend label per study, in order")
    compare.add_argument("--output", help="folder for the figures (default: compare/ next to the first study)")


def main(argv=None):
    """Entry point; returns the exit status (0 converged, 1 a level did not, 2 bad input)."""
    args = build_parser().parse_args(argv)
    setup_logging()
    if args.command != "run":
        from . import commands
        return guard.supervise(lambda: commands.COMMANDS[args.command](args))
    return guard.supervise(lambda: _run_command(args))  # signals, and faults on one rank of several


def _run_command(args):
    try:
        cfg = _load(args)
        _check_output(cfg, args.force or args.resume)
        done = _prepare(cfg, args)
    except (ConfigError, yaml.YAMLError, OSError) as err:
        return _fail(args.config, err)
    return run(cfg, quiet=args.quiet, verbose=args.verbose, done=done)


def run(cfg, quiet=False, verbose=False, done=()):
    """Run the study (after the levels `done`), writing results and status after each solve, with
    progress, the table(s), the verdict, tables and plots on rank 0; any study type."""
    from mpi4py import MPI
    from . import progress, report, results, study, verdict
    comm = MPI.COMM_WORLD
    run_cfg = with_monitors(cfg) if verbose else cfg  # Watch below records cfg: no monitors in the hash
    levels_study = cfg.study_type in results.LEVEL_STUDIES
    shown = progress.Progress(cfg, show=comm.rank == 0 and not quiet and levels_study)
    shown.level = len(done)  # a resumed study starts further on
    if done and comm.rank == 0 and not quiet:
        print(f"study {cfg.study}: resuming after level {done[-1].index}")

    def on_level(result):
        shown.level_done(watch.level_done(result))

    with guard.Watch(cfg, done, comm) as watch:
        result = study.run_study(run_cfg, on_level=on_level, comm=comm,
                                 monitor=None if verbose or quiet else shown.monitor, done=done)
    summary = verdict.summarize(cfg, result) if levels_study else None
    if comm.rank == 0:
        text = _outputs(cfg, result, summary)
        if not quiet:
            print(text)
    if summary is not None and not summary.met:  # the user's `expect:` block: batch runs gate on it
        return EXIT_EXPECTATION_NOT_MET
    return EXIT_OK if all(solve.outcome.converged for solve in result) else EXIT_NOT_CONVERGED


def _outputs(cfg, result, summary):
    """Write the study's tables and plots (rank 0) and return what the terminal shows."""
    from . import report, results, verdict
    if summary is None:
        named = results.limit_tables(cfg, result)
        return report.limit_summary(cfg, named, report.write_limit(cfg, result, named))
    rows = results.table(result)
    written = report.write(report.Study(cfg.study, cfg.output_dir, rows), cfg, cfg.output.digits,
                           plots=cfg.output.plots)
    return "\n".join([f"study {cfg.study}: {cfg.output_dir}", report.format_table(rows),
                      verdict.format_summary(summary), "wrote " + ", ".join(path.name for path in written)])


def with_monitors(cfg):
    """cfg with PETSc's SNES/KSP monitors switched on (--verbose); the user's own options win."""
    monitors = (("snes_monitor", ""), ("snes_converged_reason", ""), ("ksp_converged_reason", ""))
    solver = dataclasses.replace(cfg.solver, petsc_options=monitors + cfg.solver.petsc_options)
    return dataclasses.replace(cfg, solver=solver)


def _load(args):
    from . import config
    overrides = list(args.set) + ([f"output.dir={args.output}"] if args.output else [])
    return config.load(args.config, overrides)


def _prepare(cfg, args):
    """The finished levels to continue from (--resume), once the finest level fits in memory."""
    from mpi4py import MPI
    from . import resources, resume
    if not args.force:
        resources.check_memory(cfg, MPI.COMM_WORLD)
    if cfg.mesh.kind == "gmsh":  # what gmsh cannot mesh is bad input, found before any level runs
        from . import geometries
        list(geometries.mesh_levels(cfg, MPI.COMM_WORLD))
    if args.resume and cfg.study_type != "refinement":
        raise ConfigError("--resume", f"study_type {cfg.study_type} runs from the start; use --force")
    return resume.finished_levels(cfg, MPI.COMM_WORLD) if args.resume else []


def _check_output(cfg, force):
    if any((cfg.output_dir / name).exists() for name in ("rates.csv", "study.h5")) and not force:
        raise ConfigError("output.dir", f"{cfg.output_dir} already holds results; use --resume to continue "
                                        "them or --force to overwrite")  # study.h5: also studies without rates.csv


def _fail(source, err):
    from mpi4py import MPI
    if MPI.COMM_WORLD.rank == 0:
        message = _yaml_message(err) if isinstance(err, yaml.YAMLError) else str(err)
        message = " ".join(message.split("\n"))  # one line, always
        print(f"signorini: error: {source}: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT


def _yaml_message(err):
    mark = getattr(err, "problem_mark", None)
    where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
    context, start = getattr(err, "context", None), getattr(err, "context_mark", None)
    # PyYAML notices an unclosed bracket or quote where the next token is; say where it was opened
    opened = f" ({context} at line {start.line + 1}, column {start.column + 1})" if context and start else ""
    return f"YAML syntax error: {where}{getattr(err, 'problem', None) or err}{opened}"


def setup_logging(level=logging.WARNING):
    """Warnings only. FFCx's JIT logs every compilation at INFO through the root logger, and
    setuptools' distutils log resets the root level when it compiles, so filter at the handler."""
    handler = logging.StreamHandler(sys.stderr)
    handler.setLevel(level)
    handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    root = logging.getLogger()
    root.handlers[:] = [handler]
    root.setLevel(level)


def entry():
    """The console script: main(), and for a bug its traceback and exit status 3 (guard.CRASH_STATUS),
    apart from 1 (a level did not converge) and 2 (bad input)."""
    try:
        return main()
    except Exception:  # main() lets a bug's exception through, with its traceback, for tests and callers
        import traceback
        traceback.print_exc()
        return guard.CRASH_STATUS


if __name__ == "__main__":
    sys.exit(entry())
