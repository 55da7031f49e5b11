"""Command line: `signorini run CONFIG.yaml [--output DIR] [--set KEY=VALUE ...] [--force]`."""
import argparse
import logging
import sys

import yaml

from .config import ConfigError

EXIT_OK, EXIT_NOT_CONVERGED, EXIT_BAD_INPUT = 0, 1, 2


def build_parser():
    parser = argparse.ArgumentParser(prog="signorini", description=__doc__.split(":")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a convergence study")
    run.add_argument("config", help="study config (YAML)")
    run.add_argument("--output", help="results folder (overrides output.dir)")
    run.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                     help="override a config key, e.g. --set epsilon.theta=10 (repeatable)")
    run.add_argument("--force", action="store_true", help="overwrite existing results of this study")
    return parser


def main(argv=None):
    """Entry point; returns the exit status (0 converged, 1 a level did not, 2 bad input)."""
    args = build_parser().parse_args(argv)
    setup_logging()
    try:
        cfg = _load(args)
        _check_output(cfg, args.force)
    except (ConfigError, yaml.YAMLError, OSError) as err:
        return _fail(args.config, err)
    return run(cfg)


def run(cfg):
    """Run the study, writing results after each level and printing the table on rank 0."""
    from mpi4py import MPI
    from . import report, results, study
    comm = MPI.COMM_WORLD
    levels = study.run_study(cfg, on_level=lambda done: results.write(cfg, done))
    rows = results.table(levels)
    if comm.rank == 0:
        print(f"study {cfg.study}: {cfg.output_dir}")
        print(report.format_table(rows))
    return EXIT_OK if all(lv.outcome.converged for lv in levels) else EXIT_NOT_CONVERGED


def _load(args):
    from . import config
    overrides = list(args.set) + ([f"output.dir={args.output}"] if args.output else [])
    return config.load(args.config, overrides)


def _check_output(cfg, force):
    if (cfg.output_dir / "rates.csv").exists() and not force:
        raise ConfigError("output.dir", f"{cfg.output_dir} already holds results; use --force to overwrite")


def _fail(source, err):
    from mpi4py import MPI
    if MPI.COMM_WORLD.rank == 0:
        message = _yaml_message(err) if isinstance(err, yaml.YAMLError) else str(err)
        print(f"signorini: error: {source}: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT


def _yaml_message(err):
    mark = getattr(err, "problem_mark", None)
    where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
    return f"YAML syntax error: {where}{getattr(err, 'problem', None) or err}"


def setup_logging(level=logging.WARNING):
    """Warnings only. FFCx's JIT logs every compilation at INFO through the root logger, and
    setuptools' distutils log resets the root level when it compiles, so filter at the handler."""
    handler = logging.StreamHandler(sys.stderr)
    handler.setLevel(level)
    handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    root = logging.getLogger()
    root.handlers[:] = [handler]
    root.setLevel(level)

if __name__ == "__main__":
    sys.exit(main())
