"""Command line: `signorini run CONFIG.yaml [--output DIR] [--set KEY=VALUE ...] [--force] [--resume]
[-petsc_option [value] ...]`; check, init, list, report and compare."""
import sys

try:  # Ctrl-C while the modules load (MPI starts here too): one line, no traceback
    import argparse
    import dataclasses
    import logging
    import re
    from pathlib import Path

    import yaml
    from mpi4py import MPI

    from . import __version__, config, guard
    from .config import ConfigError
except KeyboardInterrupt:
    print("signorini: interrupted by SIGINT while starting", file=sys.stderr)
    sys.exit(130)

logger = logging.getLogger(__name__)

EXIT_OK, EXIT_NOT_CONVERGED, EXIT_BAD_INPUT = 0, 1, 2
EXIT_EXPECTATION_NOT_MET = 1  # an `expect:` rate was missed (issue 4)


CONFIG_HELP = f"study config (YAML; its keys: {config.DOCS}, or `signorini init`)"
PETSC_HELP = ("PETSc options such as -snes_monitor or -ksp_rtol 1e-8 may follow the config (or `--`): they join "
              "solver.petsc_options, under the study's prefix")


def build_parser():
    parser = argparse.ArgumentParser(prog="signorini", description=__doc__.split(":")[0],
                                     epilog=f"Config keys: {config.DOCS}; `signorini init` prints every key "
                                            "with its default.")
    parser.add_argument("--version", action=_Version)
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a convergence study", epilog=PETSC_HELP)
    run.add_argument("config", help=CONFIG_HELP)
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
    check = sub.add_parser("check", help="validate a config and print its resolved settings, no solve",
                           epilog=PETSC_HELP)
    check.add_argument("config", help=CONFIG_HELP)
    check.add_argument("--output", help="results folder (overrides output.dir)")
    check.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                       help="override a config key, as for run (repeatable)")
    init = sub.add_parser("init", help="a commented config with every key and its default",
                          description=f"Every config key with its default and a one-line description "
                                      f"(more in {config.DOCS}); valid as it stands.")
    init.add_argument("file", nargs="?", help="write it here (default: print it)")
    init.add_argument("--force", action="store_true", help="overwrite FILE")
    listing = sub.add_parser("list", help="the shipped configs with their descriptions")
    listing.add_argument("folder", nargs="?", help="a folder of configs (default: the shipped configs/)")
    rep = sub.add_parser("report", help="tables and plots of a finished or partial study, no recomputation")
    rep.add_argument("path", help="a study folder, its study.h5 or its rates.csv")
    rep.add_argument("--digits", type=int, help="digits after the point in rates.md/rates.tex "
                                                "(default: the study's output.digits, else 3)")
    rep.add_argument("--columns", metavar="SET", help="table columns: paper (the default: N, h, eps, Newton, the "
                     "norms the paper bounds), all, or a comma-separated list (default: the study's output.columns)")
    rep.add_argument("--width", metavar="LENGTH", help="figure width, e.g. 390pt or 5.4in (default: the study's "
                     "output.figure_width, else 345pt)")
    rep.add_argument("--per-norm", action="store_true", help="also one convergence figure per norm")
    rep.add_argument("--no-plots", action="store_true", help="tables only (matplotlib not imported)")
    rep.add_argument("--output", help="write into this folder instead of the study's")
    compare = sub.add_parser("compare", help="overlay the curves of several studies")
    compare.add_argument("paths", nargs="+", help="study folders (or their study.h5 / rates.csv)")
    compare.add_argument("--label", action="append", metavar="NAME", help="a legend label per study, in order")
    compare.add_argument("--output", help="folder for the figures (default: compare/ next to the first study)")


class _Version(argparse.Action):
    """--version: the package's and dolfinx's versions (dolfinx imported only when asked)."""

    def __init__(self, option_strings, dest, **kwargs):
        super().__init__(option_strings, dest, nargs=0, help="print the versions of signorini and dolfinx")

    def __call__(self, parser, namespace, values, option_string=None):
        import dolfinx
        print(f"signorini {__version__} (dolfinx {dolfinx.__version__})")
        parser.exit()


PETSC_OPTION = re.compile(r"^-[A-Za-z]\w*$")  # -snes_monitor; not --set, not a negative number
TAKES_VALUE = ("--set", "--output")


def split_petsc_options(argv):
    """(argv without PETSc options, [(name, value)]) for run and check: `-name [value]` tokens after the
    command, and every token after `--`. A value is the next token unless it is an option itself."""
    rest, options, i, after_dash = [], [], 0, False
    while i < len(argv):
        token = argv[i]
        if token == "--" and not after_dash:
            after_dash, i = True, i + 1
        elif token in TAKES_VALUE and not after_dash:
            rest, i = rest + argv[i:i + 2], i + 2
        elif PETSC_OPTION.match(token) and token != "-h":
            has_value = i + 1 < len(argv) and not PETSC_OPTION.match(argv[i + 1]) and argv[i + 1] != "--"
            options.append((token[1:], argv[i + 1] if has_value else ""))
            i += 2 if has_value else 1
        elif after_dash:
            raise ConfigError("--", f"{token!r} is not a PETSc option (-name [value])")
        else:
            rest, i = rest + [token], i + 1
    return rest, options


def main(argv=None):
    """Entry point; returns the exit status (0 converged, 1 a level did not, 2 bad input)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    options = []
    if argv[:1] in (["run"], ["check"]):
        try:
            argv, options = split_petsc_options(argv)
        except ConfigError as err:  # named after the config, as every bad input of run and check is
            return _fail(next((t for t in argv[1:] if not t.startswith("-")), "command line"), err)
    args = build_parser().parse_args(argv)
    args.petsc_options = options
    setup_logging()
    if args.command == "init":
        return init(args)
    if args.command != "run":
        from . import commands
        return guard.supervise(lambda: commands.COMMANDS[args.command](args))
    return guard.supervise(lambda: _run_command(args))  # signals, and faults on one rank of several


def _run_command(args):
    try:
        cfg = _load(args)
        lock = guard.FolderLock(cfg.output_dir, MPI.COMM_WORLD)  # writable, and no other run writes it
    except (ConfigError, yaml.YAMLError, OSError) as err:
        return _fail(args.config, err)
    with lock:
        try:
            _check_output(cfg, args.force or args.resume)
            done = _prepare(cfg, args)
        except (ConfigError, yaml.YAMLError, OSError) as err:
            return _fail(args.config, err)
        return run(cfg, quiet=args.quiet, verbose=args.verbose, done=done)


def run(cfg, quiet=False, verbose=False, done=()):
    """Run the study (after the levels `done`), writing results and status after each solve, with
    progress, the table(s), the verdict, tables and plots on rank 0 (any study type); status.txt says
    complete once the plots are written."""
    from . import progress, report, results, solver, study, verdict
    guard.raise_on_closed_pipes()  # after PETSc's initialisation (study imports it), which traps SIGPIPE
    solver.forget_read_options()  # _warn_unused_options: this run's solves only
    comm = MPI.COMM_WORLD
    run_cfg = with_monitors(cfg) if verbose else cfg  # Watch below records cfg: no monitors in the hash
    levels_study = cfg.study_type in results.LEVEL_STUDIES
    shown = progress.Progress(cfg, show=comm.rank == 0 and not quiet and levels_study)
    shown.level = len(done)  # a resumed study starts further on
    if done and comm.rank == 0 and not quiet:
        with guard.stdout_may_close():
            print(f"study {cfg.study}: resuming after level {done[-1].index}")

    def on_level(result):
        shown.level_done(watch.level_done(result))
        solved = len(list(result))
        if solved == len(done) + 1 and comm.rank == 0:  # the run's first solve: its options were read
            _warn_unused_options(solver.unused_options([name for name, _ in cfg.solver.petsc_options]),
                                 solved - 1)

    with guard.Watch(cfg, done, comm) as watch:
        result = study.run_study(run_cfg, on_level=on_level, comm=comm,
                                 monitor=None if verbose or quiet else shown.monitor, done=done)
        summary = verdict.summarize(cfg, result) if levels_study else None
        text = watch.finish(lambda: _outputs(cfg, result, summary))
    if comm.rank == 0 and not quiet:
        with guard.stdout_may_close():  # `| head -1`: the files above are whole, the printing stops
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
    return "\n".join([f"study {cfg.study}: {cfg.output_dir}", report.format_table(rows, cfg),
                      verdict.format_summary(summary), "wrote " + ", ".join(path.name for path in written)])


def _warn_unused_options(unused, level):
    """Name the user's PETSc options that level `level`'s solves did not read (misspelt, or for
    an object the study does not create): PETSc itself ignores them in silence."""
    if unused:
        logger.warning("solver.petsc_options: %s not used by PETSc in level %d (misspelt, or not an option "
                       "of the solver and preconditioner in use)", ", ".join(unused), level)


def with_monitors(cfg):
    """cfg with PETSc's SNES/KSP monitors switched on (--verbose); the user's own options win."""
    monitors = (("snes_monitor", ""), ("snes_converged_reason", ""), ("ksp_converged_reason", ""))
    solver = dataclasses.replace(cfg.solver, petsc_options=monitors + cfg.solver.petsc_options)
    return dataclasses.replace(cfg, solver=solver)


def _load(args):
    overrides = list(args.set) + ([f"output.dir={args.output}"] if args.output else [])
    return config.load(args.config, overrides, getattr(args, "petsc_options", ()))


def init(args):
    """Print (or write to FILE) the commented config of every key with its default."""
    from mpi4py import MPI
    text = config.template()
    if args.file is None:
        if MPI.COMM_WORLD.rank == 0:
            print(text, end="")
        return EXIT_OK
    if Path(args.file).exists() and not args.force:
        return _fail(args.file, ConfigError("", "already exists; use --force to overwrite it"))
    try:
        if MPI.COMM_WORLD.rank == 0:
            Path(args.file).write_text(text)
    except OSError as err:
        return _fail(args.file, err)
    return EXIT_OK


def _prepare(cfg, args):
    """The finished levels to continue from (--resume), once the finest level fits in memory."""
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
    except KeyboardInterrupt:  # before the handlers of guard.supervise are in place (MPI starting)
        print("signorini: interrupted by SIGINT while starting", file=sys.stderr)
        return 128 + 2
    except BrokenPipeError:  # `signorini list | head -1`: the reader has what it wanted (report and
        guard.stdout_to_devnull()  # compare write their files before they print)
        return EXIT_OK
    except Exception:  # main() lets a bug's exception through, with its traceback, for tests and callers
        import traceback
        traceback.print_exc()
        return guard.CRASH_STATUS


if __name__ == "__main__":
    sys.exit(entry())
