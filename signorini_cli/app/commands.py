"""The commands: run (a study of any type), check (resolved config), init (the commented template), list
(shipped configs), report and compare; their exit statuses and the one-line error of bad input."""
import dataclasses
import hashlib
import logging
import os
import re
from pathlib import Path

import yaml
from mpi4py import MPI

from .. import config, studies
from ..analysis import rates, verdict
from ..config import ConfigError
from ..record import csvfile, results, resume
from ..report import plots, progress, tables, verdicts
from ..solve import solver
from ..system import errors
from . import checks, guard, maps

logger = logging.getLogger(__name__)

EXIT_OK, EXIT_NOT_CONVERGED, EXIT_BAD_INPUT = 0, 1, 2
EXIT_EXPECTATION_NOT_MET = 1  # an `expect:` rate was missed

SHIPPED_CONFIGS = Path(__file__).resolve().parents[2] / "configs"


class _FlowListDumper(yaml.SafeDumper):
    """Block mappings, but lists on one line: `refinements: [8, 16, 32]`."""


_FlowListDumper.add_representer(
    list, lambda dumper, data: dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=True))


def check(args):
    """Validate CONFIG (with --set/--output) and print its resolved settings as YAML, no solve."""
    try:
        cfg = _load(args)
    except (ConfigError, yaml.YAMLError, OSError) as err:
        return fail(args.config, err)
    if MPI.COMM_WORLD.rank == 0:  # no dolfinx/PETSc import: check stays instant (and `| head` safe)
        emit([f"# {args.config}: valid. Resolved settings, every default filled in:",
              yaml.dump(config.to_dict(cfg), Dumper=_FlowListDumper, sort_keys=False, allow_unicode=True).rstrip("\n"),
              f"# results would go to {cfg.output_dir}/"])
    return EXIT_OK


def list_configs(args):
    """Every configs/**/*.yaml as a path to give `run`, with its one-line description (or why it does
    not load)."""
    folder = Path(args.folder) if args.folder else shipped_configs()
    if not folder.is_dir():
        return fail(str(folder), OSError("not a folder of configs"))
    paths = [_shown_path(path) for path in sorted(folder.glob("**/*.yaml"))]
    width = max(map(len, paths), default=0)
    if MPI.COMM_WORLD.rank == 0:
        emit(f"{path:<{width}}  {_description(path)}" for path in paths)
    return EXIT_OK


def _shown_path(path):
    """The path relative to the working folder when it lies below it, else absolute."""
    relative = os.path.relpath(path.resolve())
    return relative if not relative.startswith("..") else str(path.resolve())


def emit(lines):
    """Print the lines to stdout; a reader that stops early (`| head -1`) ends the output quietly: the
    work is done, the rest of stdout goes to /dev/null (no BrokenPipeError at exit)."""
    with guard.stdout_may_close():
        for line in lines:
            print(line)


def shipped_configs():
    """configs/ of this checkout, else of the current folder."""
    return SHIPPED_CONFIGS if SHIPPED_CONFIGS.is_dir() else Path("configs")


def _description(path):
    try:
        return config.load(path).description or "(no description)"
    except (ConfigError, yaml.YAMLError, OSError) as err:
        return f"(invalid: {str(err).splitlines()[0]})"


def report_study(args):
    """Tables and plots of a finished or partial study of any type from its study.h5 (or rates.csv) (a map: map.csv,
    its figures and tables from its points' folders)."""
    if maps.is_map(args.path):
        return report_map(args)
    try:
        study = results.load(args.path)
        cfg = study_config(study)
        digits = args.digits if args.digits is not None else (cfg.output.digits if cfg is not None else 3)
        if digits < 1:
            raise ConfigError("--digits", f"must be >= 1, got {digits}")
        columns = config.table_columns(args.columns, "--columns") if args.columns else None
        figure = {"width": config.length(args.width, "--width") if args.width else None,
                  "per_norm": args.per_norm, "font": args.font or "cm"}
        folder = Path(args.output or study.folder)
        beside = args.columns and folder.resolve() == study.folder.resolve()
        written, summary = [], recorded_verdict(study, cfg)
        if MPI.COMM_WORLD.rank == 0:  # other columns beside the study's own files, never over them
            written = tables.write(study, cfg, digits, plots=not args.no_plots, folder=folder, columns=columns,
                                   figure=figure, suffix=columns_suffix(args.columns) if beside else "",
                                   summary=summary)
            table = tables.terminal(study, cfg) if columns is None else tables.format_table(study.rows, cfg, columns)
    except (ConfigError, OSError) as err:
        return fail(args.path, err)
    if MPI.COMM_WORLD.rank == 0:
        shown = [verdicts.format_summary(summary)] if summary is not None and columns is None else []
        emit([f"study {study.name}: {_levels_done(study, cfg)} from {args.path}", table] + shown
             + [tables.wrote((p.relative_to(folder) for p in written), folder)])
    return EXIT_OK


def recorded_verdict(study, cfg):
    """The verdict the run recorded (its summary.csv), as run printed it; None without one (a type without a
    verdict, a study read from rates.csv alone, a summary.csv of an older format)."""
    path = study.folder / "summary.csv"
    if cfg is None or not path.exists():
        return None
    try:
        return verdict.from_rows(cfg, csvfile.read(path))
    except (csvfile.Damaged, KeyError):
        logger.warning("%s: no verdict read (damaged, or written by an older version)", path)
        return None


def columns_suffix(columns):
    """"-N-h-L2" for `--columns N,h,L2`: a file name part (long lists cut, a hash keeps them apart)."""
    slug = "-".join(re.sub(r"[^A-Za-z0-9_]+", "", c) for c in columns.split(","))
    if len(slug) > 48:
        slug = slug[:39] + "-" + hashlib.sha256(columns.encode()).hexdigest()[:8]
    return "-" + slug


def report_map(args):
    """A map's outputs redrawn from its folder (into --output instead when given); the options of a study's
    tables are refused, a map has none of them."""
    try:
        given = [flag for flag, value in (("--digits", args.digits), ("--columns", args.columns),
                                          ("--width", args.width), ("--per-norm", args.per_norm),
                                          ("--font", args.font)) if value]
        if given:
            raise ConfigError(given[0], "applies to a study's tables and figures; a map's report has no such option")
        text = maps.report(args.path, not args.no_plots, args.output) if MPI.COMM_WORLD.rank == 0 else None
    except (ConfigError, yaml.YAMLError, OSError) as err:
        return fail(args.path, err)
    if text:
        emit([text])
    return EXIT_OK


def study_config(study):
    """The study's config from its record (resolved when recorded), or None (rates.csv, older schema)."""
    if not study.config_text:
        return None
    try:
        return config.loads(study.config_text)
    except (ConfigError, yaml.YAMLError):
        return None


def _levels_done(study, cfg):
    if studies.of(study.study_type).UNIT != "levels":
        return f"{study.study_type}, {len(study.rows)} rows in its main table"
    done = len(study.rows)
    if cfg is None or done >= len(cfg.mesh.levels):
        return f"{done} level{'s' if done != 1 else ''}"
    return f"{done} of {len(cfg.mesh.levels)} levels (partial study)"


def compare(args):
    """Overlay several studies of any type (what each type compares: its rate tables): error vs h and vs
    time per norm, Newton iterations; a summary table."""
    try:
        found = [_load_one(path) for path in args.paths]
    except _BadStudy as err:  # name the one folder that does not load
        return fail(err.path, err.cause)
    try:
        if args.label and len(args.label) != len(found):
            raise ConfigError("--label", f"give one per study: {len(found)} studies, {len(args.label)} labels")
        labels = args.label or _labels(found)
        twice = next((label for label in labels if labels.count(label) > 1), None)
        if twice is not None:  # one label would stand for two studies in the legend and the table
            raise ConfigError("--label", f"{twice!r} names two of the studies; give each its own label")
        folder = Path(args.output) if args.output else found[0].folder.parent / compare_folder(labels)
        rows = {f"{label} {part}".strip(): part_rows for label, study in zip(labels, found)
                for part, part_rows in compared(study).items()}
        fit_levels = {f"{label} {part}".strip(): _fit_levels(study) for label, study in zip(labels, found)
                      for part in compared(study)}  # each study fitted as its own verdict fits it
        written = []
        if MPI.COMM_WORLD.rank == 0:
            written = tables.write_comparison(rows, folder, fit_levels) + plots.write_comparison(rows, folder)
    except (ConfigError, OSError) as err:
        return fail("compare", err)
    if MPI.COMM_WORLD.rank == 0:
        emit([tables.summary_table(rows, fit_levels), tables.wrote((p.name for p in written), folder)])
    return EXIT_OK


def compare_folder(labels):
    """compare-<label>-<label>...: a comparison's default folder named for its inputs, so that the next
    comparison of other studies does not write over it (long lists cut, a hash keeps them apart)."""
    slug = "-".join(re.sub(r"[^A-Za-z0-9_.]+", "_", label).strip("_") for label in labels)
    if len(slug) > 60:
        slug = slug[:51] + "-" + hashlib.sha256("\0".join(labels).encode()).hexdigest()[:8]
    return "compare-" + slug


def _fit_levels(study):
    """The levels a study's rates are fitted over: its config's verification.fit_levels (the default
    without a config)."""
    cfg = study_config(study)
    return cfg.verification.fit_levels if cfg is not None else rates.FIT_LEVELS


def compared(study):
    """{label suffix: rate-table rows} of a study read back, as its type compares it."""
    return studies.of(study.study_type).compared(study.tables or {"rates": study.rows})


class _BadStudy(OSError):
    """One study of a comparison that does not load: its path and why."""

    def __init__(self, path, cause):
        super().__init__(str(cause))
        self.path, self.cause = path, cause


def _load_one(path):
    try:
        return results.load(path)
    except (ConfigError, OSError) as err:
        raise _BadStudy(path, err) from None


def _labels(found):
    """Study names, made unique with their folders where two studies share a name."""
    names = [study.name for study in found]
    return [name if names.count(name) == 1 else f"{name} ({study.folder})" for name, study in zip(names, found)]




def _run_command(args):
    try:
        cfg = _load(args)
        if studies.of(cfg.study_type).POINTS:
            return _run_map(cfg, args)
        if args.points is not None:
            raise ConfigError("--points", f"chooses points of a map; study_type is {cfg.study_type}")
        lock = guard.FolderLock(cfg.output_dir, MPI.COMM_WORLD)  # writable, and no other run writes it
    except (ConfigError, yaml.YAMLError, OSError) as err:
        return fail(args.config, err)
    with lock:
        try:
            _check_output(cfg, args.force or args.resume)
            done = _prepare(cfg, args)
            if args.force and not args.resume and MPI.COMM_WORLD.rank == 0:
                results.start_over(cfg.output_dir)  # under the lock (no other run writes there), once nothing refuses
        except (ConfigError, yaml.YAMLError, OSError) as err:
            return fail(args.config, err)
        status = results.read_status(cfg.output_dir) if MPI.COMM_WORLD.rank == 0 else ""
        try:
            return run(cfg, quiet=args.quiet, verbose=args.verbose, done=done)
        except ConfigError as err:  # refused before solving: a problem not posed right (problems/posed.py), or an
            # option PETSc rejects only in a real solve (on every rank)
            if MPI.COMM_WORLD.rank == 0:
                results.restore(cfg, done, status, MPI.COMM_WORLD.size)  # bad input leaves the folder as it found it
            return fail(args.config, err)


def _run_map(cfg, args):
    """A map: on map.jobs local workers (under mpirun); which runs may write one map folder at once:
    maps.run."""
    if cfg.map.jobs > 1 and MPI.COMM_WORLD.size == 1:
        maps.relaunch(cfg.map.jobs)
    try:
        ran = maps.run(cfg, args.points, force=args.force, resume_map=args.resume, quiet=args.quiet,
                       memory=not args.ignore_memory_check)
        return maps.exit_status(ran, MPI.COMM_WORLD)
    except (ConfigError, OSError) as err:
        return fail(args.config, err)


def run(cfg, quiet=False, verbose=False, done=()):
    """Run the study (after the levels `done`), writing results and status after each solve, with
    progress, the table(s), the verdict, tables and plots on rank 0 (any study type); status.txt says
    complete once the plots are written."""
    solver.forget_read_options()  # _warn_unused_options: this run's solves only
    comm = MPI.COMM_WORLD
    run_cfg = with_monitors(cfg) if verbose else cfg  # Watch below records cfg: no monitors in the hash
    kind = studies.of(cfg.study_type)
    shown = progress.Progress(cfg, show=comm.rank == 0 and not quiet and kind.UNIT == "levels")
    shown.level = len(done)  # a resumed study starts further on
    if done and comm.rank == 0 and not quiet:
        with guard.stdout_may_close():
            print(f"study {cfg.study}: resuming after level {done[-1].index}")

    def on_study(study):
        shown.level_done(watch.level_done(study))
        if study.solves == len(done) + 1 and comm.rank == 0:  # the run's first solve: its options were read
            _warn_unused_options(solver.unused_options([name for name, _ in cfg.solver.petsc_options]),
                                 study.solves - 1)

    with guard.Watch(cfg, done, comm) as watch:
        study = studies.run(cfg, on_study, comm, None if verbose or quiet else shown.monitor, done, run_cfg)
        text = watch.finish(lambda: _outputs(study))
    if comm.rank == 0 and not quiet:
        with guard.stdout_may_close():  # `| head -1`: the files above are whole, the printing stops
            print(text)
    if not study.met:  # the user's `expect:` block: batch runs gate on it
        return EXIT_EXPECTATION_NOT_MET
    return EXIT_OK if study.converged else EXIT_NOT_CONVERGED


def _outputs(study):
    """Write the study's tables and plots (rank 0) and return what the terminal shows."""
    cfg = study.config
    record = results.Study(cfg.study, cfg.output_dir, study.rows, study_type=cfg.study_type, tables=study.tables)
    written = tables.write(record, cfg, cfg.output.digits, plots=cfg.output.plots, summary=study.summary)
    header = (f"study {cfg.study} ({cfg.study_type}): {cfg.output_dir} "
              f"(contact term: contact_quadrature {cfg.contact_quadrature})")
    shown = [verdicts.format_summary(study.summary)] if study.summary is not None else []
    files = [str(path.relative_to(cfg.output_dir)) for path in written]
    return "\n".join([header, tables.terminal(record, cfg)] + shown + [tables.wrote(files)])


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
    text = config.template()
    if args.file is None:
        if MPI.COMM_WORLD.rank == 0:
            print(text, end="")
        return EXIT_OK
    if Path(args.file).exists() and not args.force:
        return fail(args.file, ConfigError("", "already exists; use --force to overwrite it"))
    try:
        if MPI.COMM_WORLD.rank == 0:
            Path(args.file).write_text(text)
    except OSError as err:
        return fail(args.file, err)
    if MPI.COMM_WORLD.rank == 0:
        emit([f"wrote {args.file}: every config key at its default, each with a one-line comment"])
    return EXIT_OK


def _prepare(cfg, args):
    """The finished levels to continue from (--resume), once the finest level fits in memory and PETSc took
    the user's options on a small system."""
    checks.before_solving(cfg, MPI.COMM_WORLD, memory=not args.ignore_memory_check)
    return resume.finished_levels(cfg, MPI.COMM_WORLD) if args.resume else []


def _check_output(cfg, force):
    if any((cfg.output_dir / name).exists() for name in ("rates.csv", "study.h5")) and not force:
        raise ConfigError("output.dir", f"{cfg.output_dir} already holds results; use --resume to continue "
                                        "them or --force to overwrite")  # study.h5: also studies without rates.csv


def fail(source, err):
    """The one error line (rank 0) of bad input; exit status 2."""
    if MPI.COMM_WORLD.rank == 0:
        errors.print_error(source, _yaml_message(err) if isinstance(err, yaml.YAMLError) else err)
    return EXIT_BAD_INPUT


def _yaml_message(err):
    mark = getattr(err, "problem_mark", None)
    where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
    context, start = getattr(err, "context", None), getattr(err, "context_mark", None)
    # PyYAML notices an unclosed bracket or quote where the next token is; say where it was opened
    opened = f" ({context} at line {start.line + 1}, column {start.column + 1})" if context and start else ""
    return f"YAML syntax error: {where}{getattr(err, 'problem', None) or err}{opened}"


COMMANDS = {"run": _run_command, "check": check, "list": list_configs, "report": report_study, "compare": compare}
