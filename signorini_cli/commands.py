"""The commands besides `run`: check (resolved config), list (shipped configs), report and compare."""
import os
import sys
from pathlib import Path

import yaml
from mpi4py import MPI

from . import cli, config, plots, report
from .config import ConfigError

SHIPPED_CONFIGS = Path(__file__).resolve().parent.parent / "configs"


class _FlowListDumper(yaml.SafeDumper):
    """Block mappings, but lists on one line: `refinements: [8, 16, 32]`."""


_FlowListDumper.add_representer(
    list, lambda dumper, data: dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=True))


def check(args):
    """Validate CONFIG (with --set/--output) and print its resolved settings as YAML, no solve."""
    try:
        cfg = cli._load(args)
    except (ConfigError, yaml.YAMLError, OSError) as err:
        return cli._fail(args.config, err)
    if MPI.COMM_WORLD.rank == 0:  # no dolfinx/PETSc import: check stays instant (and `| head` safe)
        emit([f"# {args.config}: valid. Resolved settings, every default filled in:",
              yaml.dump(config.to_dict(cfg), Dumper=_FlowListDumper, sort_keys=False, allow_unicode=True).rstrip("\n"),
              f"# results would go to {cfg.output_dir}/"])
    return cli.EXIT_OK


def list_configs(args):
    """Every configs/**/*.yaml as a path to give `run`, with its one-line description (or why it does
    not load)."""
    folder = Path(args.folder) if args.folder else shipped_configs()
    if not folder.is_dir():
        return cli._fail(str(folder), OSError("not a folder of configs"))
    paths = [_shown_path(path) for path in sorted(folder.glob("**/*.yaml"))]
    width = max(map(len, paths), default=0)
    if MPI.COMM_WORLD.rank == 0:
        emit(f"{path:<{width}}  {_description(path)}" for path in paths)
    return cli.EXIT_OK


def _shown_path(path):
    """The path relative to the working folder when it lies below it, else absolute."""
    relative = os.path.relpath(path.resolve())
    return relative if not relative.startswith("..") else str(path.resolve())


def emit(lines):
    """Print the lines to stdout; a reader that stops early (`| head -1`) ends the output quietly: the
    work is done, the rest of stdout goes to /dev/null (no BrokenPipeError at exit)."""
    try:
        for line in lines:
            print(line)
        sys.stdout.flush()
    except BrokenPipeError:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)


def shipped_configs():
    """configs/ of this checkout, else of the current folder."""
    return SHIPPED_CONFIGS if SHIPPED_CONFIGS.is_dir() else Path("configs")


def _description(path):
    try:
        return config.load(path).description or "(no description)"
    except (ConfigError, yaml.YAMLError, OSError) as err:
        return f"(invalid: {str(err).splitlines()[0]})"


def report_study(args):
    """Tables and plots of a finished or partial study from its study.h5 or rates.csv."""
    try:
        study = report.load(args.path)
        cfg = study_config(study)
        digits = args.digits if args.digits is not None else (cfg.output.digits if cfg is not None else 3)
        if digits < 1:
            raise ConfigError("--digits", f"must be >= 1, got {digits}")
        columns = _columns(args.columns) if args.columns else None
        figure = {"width": config.length(args.width, "--width") if args.width else None,
                  "per_norm": args.per_norm}
        written = []
        if MPI.COMM_WORLD.rank == 0:
            written = report.write(study, cfg, digits, plots=not args.no_plots, folder=args.output,
                                   columns=columns, figure=figure)
            table = report.format_table(study.rows, cfg, columns)
    except (ConfigError, OSError) as err:
        return cli._fail(args.path, err)
    if MPI.COMM_WORLD.rank == 0:
        emit([f"study {study.name}: {_levels_done(study, cfg)} from {args.path}", table,
              f"wrote into {Path(args.output or study.folder)}: " + ", ".join(p.name for p in written)])
    return cli.EXIT_OK


def study_config(study):
    """The study's config from its record (resolved when recorded), or None (rates.csv, older schema)."""
    if not study.config_text:
        return None
    try:
        return config.loads(study.config_text)
    except (ConfigError, yaml.YAMLError):
        return None


def _levels_done(study, cfg):
    done = len(study.rows)
    if cfg is None or done >= len(cfg.mesh.levels):
        return f"{done} level{'s' if done != 1 else ''}"
    return f"{done} of {len(cfg.mesh.levels)} levels (partial study)"


def compare(args):
    """Overlay several studies: error vs h and vs time per norm, Newton iterations; a summary table."""
    try:
        studies = [_load_one(path) for path in args.paths]
    except _BadStudy as err:  # name the one folder that does not load
        return cli._fail(err.path, err.cause)
    try:
        if args.label and len(args.label) != len(studies):
            raise ConfigError("--label", f"give one per study: {len(studies)} studies, {len(args.label)} labels")
        labels = args.label or _labels(studies)
        folder = Path(args.output) if args.output else studies[0].folder.parent / "compare"
        rows = dict(zip(labels, (study.rows for study in studies)))
        written = plots.write_comparison(rows, folder) if MPI.COMM_WORLD.rank == 0 else []
    except (ConfigError, OSError) as err:
        return cli._fail("compare", err)
    if MPI.COMM_WORLD.rank == 0:
        emit([report.summary_table(rows), f"wrote into {folder}: " + ", ".join(p.name for p in written)])
    return cli.EXIT_OK


class _BadStudy(OSError):
    """One study of a comparison that does not load: its path and why."""

    def __init__(self, path, cause):
        super().__init__(str(cause))
        self.path, self.cause = path, cause


def _load_one(path):
    try:
        return report.load(path)
    except (ConfigError, OSError) as err:
        raise _BadStudy(path, err) from None


def _labels(studies):
    """Study names, made unique with their folders where two studies share a name."""
    names = [study.name for study in studies]
    return [name if names.count(name) == 1 else f"{name} ({study.folder})" for name, study in zip(names, studies)]


COMMANDS = {"check": check, "list": list_configs, "report": report_study, "compare": compare}


def _columns(text):
    """--columns: paper, all, or column names separated by commas."""
    value = text if text in config.TABLE_COLUMNS else text.split(",")
    return config.table_columns(value, "--columns")
