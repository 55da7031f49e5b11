"""Command line: `signorini run CONFIG.yaml [--output DIR] [--set KEY=VALUE ...] [--force] [--resume]
[-petsc_option [value] ...]`; check, init, list, report and compare."""
import os
import sys


def open_closed_descriptors():
    """A standard descriptor closed at start (`signorini run cfg >&-`) is opened on /dev/null before MPI or
    a results file can take its number (the printing would go into that file)."""
    for fd, name in ((0, "stdin"), (1, "stdout"), (2, "stderr")):
        try:
            os.fstat(fd)
        except OSError:
            os.open(os.devnull, os.O_RDWR)  # the lowest free descriptor: fd itself
        if getattr(sys, name) is None:  # Python saw it closed as it started; modules (ufl) expect a stream
            setattr(sys, name, open(fd, "r" if fd == 0 else "w", closefd=False))


open_closed_descriptors()

try:  # Ctrl-C while the modules load (MPI starts with commands' imports): one line, no traceback
    import argparse
    import logging
    import re

    from mpi4py import MPI

    from ..config import ConfigError
    from ..system.version import version_line
    from . import commands, guard
    from .commands import EXIT_BAD_INPUT, EXIT_EXPECTATION_NOT_MET, EXIT_NOT_CONVERGED, EXIT_OK  # noqa: F401
except KeyboardInterrupt:
    print("signorini: interrupted by SIGINT while starting", file=sys.stderr)
    sys.exit(130)


DESCRIPTION = "FEniCSx convergence studies of the normal compliance contact model."  # one line of --help
CONFIG_HELP = "study config (YAML; `signorini init` prints every key with its default and what it does)"
# documentation that is there wherever the package is installed: the installed command itself
DOCS_HELP = ("Config keys: `signorini init` prints every key with its default and a one-line description (the "
             "project's configuration reference says the same at more length).")
PETSC_HELP = ("PETSc options such as -snes_monitor or -ksp_rtol 1e-8 may follow the config (or `--`): they join "
              "solver.petsc_options, under the study's prefix")


class Parser(argparse.ArgumentParser):
    """argparse's parser, with its errors as every bad input of signorini: one line, exit 2 (not the usage)."""

    def error(self, message):
        if MPI.COMM_WORLD.rank == 0:
            print(f"signorini: error: command line: {' '.join(message.split())} (see `{self.prog} --help`)",
                  file=sys.stderr)
        sys.exit(EXIT_BAD_INPUT)


def build_parser():
    parser = Parser(prog="signorini", description=DESCRIPTION,
                                     epilog=DOCS_HELP)
    parser.add_argument("--version", action=_Version)
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a convergence study", epilog=PETSC_HELP)
    run.add_argument("config", help=CONFIG_HELP)
    run.add_argument("--output", help="results folder (overrides output.dir)")
    run.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                     help="override a config key, e.g. --set epsilon.theta=10 (repeatable)")
    run.add_argument("--force", action="store_true",
                     help="start over: the study's existing results (tables, figures, fields) are removed")
    run.add_argument("--ignore-memory-check", action="store_true",
                     help="run even when the finest level looks too big for the available memory")
    run.add_argument("--resume", action="store_true", help="continue an interrupted study from its first "
                                                           "unfinished level (the config must be unchanged)")
    run.add_argument("--points", metavar="RANGES", help="a map: run only these points, e.g. 0-49 or 0-9,20 "
                                                        "(a batch array job's chunk)")
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
                          description="Every config key with its default and a one-line description; "
                                      "valid as it stands.")
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
    rep.add_argument("--font", choices=("cm", "stix", "sans"), help="the figures' font: cm (Computer Modern, "
                     "a default LaTeX article's; the default), stix (Times-like) or sans")
    rep.add_argument("--per-norm", action="store_true", help="also one convergence figure per norm")
    rep.add_argument("--no-plots", action="store_true", help="tables only (matplotlib not imported)")
    rep.add_argument("--output", help="write into this folder instead of the study's")
    compare = sub.add_parser("compare", help="overlay the curves of several studies")
    compare.add_argument("paths", nargs="+", help="study folders (or their study.h5 / rates.csv)")
    compare.add_argument("--label", action="append", metavar="NAME", help="a legend label per study, in order")
    compare.add_argument("--output", help="folder for the tables and figures (default: compare-<labels>/ next to "
                                          "the first study)")


class _Version(argparse.Action):
    """--version: the package's and dolfinx's versions (system.version: dolfinx is not imported)."""

    def __init__(self, option_strings, dest, **kwargs):
        super().__init__(option_strings, dest, nargs=0, help="print the versions of signorini and dolfinx")

    def __call__(self, parser, namespace, values, option_string=None):
        print(version_line())
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
            return commands.fail(next((t for t in argv[1:] if not t.startswith("-")), "command line"), err)
    args = build_parser().parse_args(argv)
    args.petsc_options = options
    if getattr(args, "output", None) is not None and not args.output.strip():
        return commands.fail(getattr(args, "config", None) or getattr(args, "path", None) or "command line",
                             ConfigError("--output", "is empty; give a folder (or leave --output out)"))
    setup_logging()
    guard.raise_on_closed_pipes()  # PETSc, initialised as the commands' modules load, traps SIGPIPE
    if args.command == "init":
        return commands.init(args)
    return guard.supervise(lambda: commands.COMMANDS[args.command](args))  # signals, faults on one rank


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
    guard.forgiving_streams()  # output that cannot be printed does not stop a study
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
