"""A rate map's run: every point's folder kept current as it solves (a finished point survives any
signal), then map.csv with its figures, tables and terminal summary, rebuilt from the points' folders
(so an interrupted and resumed map, or one run in chunks, ends with the same map.csv)."""
import os
import shutil
import sys
from pathlib import Path

from mpi4py import MPI

from .. import config, studies
from ..config import ConfigError
from ..config import map as map_config
from ..record import resume, results
from ..report import maps, tables
from ..studies import rate_map
from . import guard

ENDED = ("complete", "failed")  # a point whose status.txt starts so has ended: --resume keeps it
CONFIG_FILE = "config.yaml"  # the resolved config, beside a map's and every point's results


def relaunch(jobs):
    """map.jobs > 1 on one process: the same command again under `mpirun -n jobs`, one point per rank
    (this process is replaced; its folder lock ends with it and the new rank 0 takes it)."""
    mpirun = shutil.which("mpirun")
    if mpirun is None:
        raise ConfigError("map.jobs", f"{jobs} workers run under mpirun, which is not on PATH; run the map "
                                      "under mpirun -n N yourself, or set map.jobs: 1")
    sys.stdout.flush()
    # os.environ is the environment this process started with: MPI's start-up added variables of its own
    # to the C environment that would make mpirun take the new job for this one
    os.execve(mpirun, [mpirun, "-n", str(jobs), *sys.orig_argv], dict(os.environ))


def run(cfg, points=None, force=False, resume_map=False, quiet=False, comm=MPI.COMM_WORLD):
    """Run the map's points (those of the chunk `points`, e.g. "0-49", else all; with resume_map those not
    yet ended), then write map.csv, figures and tables on rank 0. Exit 0 when every point run
    converged, else 1."""
    count = len(cfg.map.studies)
    chosen = map_config.chunk(points, count) if points else list(range(count))
    ended = resume.on_rank_zero(comm, lambda: _ended(cfg, chosen)) if resume_map else set()
    if not (force or resume_map):
        resume.on_rank_zero(comm, lambda: _check_fresh(cfg, chosen, whole=not points))
    if comm.rank == 0:
        _start(cfg, count, ended)
    recorder = Recorder(cfg, comm, quiet, chunked=bool(points))
    try:
        ran = studies.run_study(cfg, on_level=recorder, comm=comm, done=(set(range(count)) - set(chosen)) | ended)
    except guard.Interrupted as sig:
        with guard.deferred(drop=True):
            recorder.interrupted()
            sig.note = (f" at map point {recorder.point.index if recorder.point else '-'}: finished points are "
                        f"in {map_config.folder_of(cfg)}; continue with --resume")
        raise
    rows = comm.gather(recorder.rows, root=0)  # the rows of the points run here: none read back from disk
    text = finish(cfg, known={k: row for part in rows for k, row in part.items()}) if comm.rank == 0 else None
    if text and not quiet:
        with guard.stdout_may_close():
            print(text)
    ok = all(p.failure == "" and p.levels and all(lv.outcome.converged for lv in p.levels) for p in ran)
    return 0 if comm.allreduce(ok, op=MPI.LAND) else 1


def point_status(cfg):
    """A point folder's status.txt line ('' when absent)."""
    path = Path(cfg.output_dir) / results.STATUS_FILE
    return path.read_text().strip() if path.exists() else ""


def _ended(cfg, chosen):
    """The chosen points that have ended, after checking their study.h5 was written for their config."""
    ended = {k for k in chosen if point_status(cfg.map.studies[k]).startswith(ENDED)}
    for k in ended:
        resume.read_levels(cfg.map.studies[k])  # ConfigError naming the keys when the config changed
    return ended


def _check_fresh(cfg, chosen, whole):
    """Refuse to overwrite results unless asked: the map's map.csv (whole runs) and the chosen points'."""
    held = [Path(cfg.map.studies[k].output_dir) for k in chosen if point_status(cfg.map.studies[k])]
    if whole and (Path(cfg.output_dir) / maps.MAP_FILE).exists():
        held.insert(0, Path(cfg.output_dir))
    if held:
        raise ConfigError("output.dir", f"{held[0]} already holds results; use --resume to continue them or "
                                        "--force to overwrite")


def _start(cfg, count, ended):
    """The map's own config and status, written as it starts."""
    folder = Path(cfg.output_dir)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / CONFIG_FILE).write_text(config.yaml_dump(config.to_dict(cfg)))
    results.write_status(folder, f"running ({len(ended)} of {count} points done)")


class Recorder:
    """on_level of a map: a point's folder prepared as the point starts and its results written once as it
    ends (its group's rank 0 writes; signals wait): a finished point is kept whole, one under way is
    solved again by --resume. A line per finished point; `rows`, map.csv's rows of the points this
    group's rank 0 finished (the same as read back from their folders)."""

    def __init__(self, cfg, comm, quiet, chunked):
        self.cfg, self.comm, self.quiet, self.chunked = cfg, comm, quiet, chunked
        self.point, self.lock, self.rows = None, None, {}

    def __call__(self, point):
        if point is not self.point:
            self.begin(point)
        if not point.done:
            return
        with guard.deferred():
            guard.results_write(studies.study_of(point.cfg, point.levels), point.comm)
            if point.failure and point.comm.rank == 0:
                results.write_status(point.cfg.output_dir, f"failed at level {len(point.levels)}: {point.failure}")
        self.end(point)

    def begin(self, point):
        """A point's folder: locked (a chunk's points: chunks of one map may run at once), emptied of an
        earlier run's files, its resolved config beside it."""
        self.point = point
        if self.chunked:
            self.lock = guard.FolderLock(point.cfg.output_dir, point.comm)
        if point.comm.rank == 0:
            folder = Path(point.cfg.output_dir)
            folder.mkdir(parents=True, exist_ok=True)
            for path in folder.iterdir():
                if path.is_file():
                    path.unlink()
            (folder / CONFIG_FILE).write_text(point.cfg.text)
            results.write_status(folder, "running")
        point.comm.barrier()

    def end(self, point):
        if self.lock is not None:
            self.lock.release()
            self.lock = None
        if point.comm.rank != 0:
            return
        row = rate_map.row(point.cfg, point.values, point.levels, point_status(point.cfg), self.cfg.map.varied)
        self.rows[point.index] = row
        if not self.quiet:
            with guard.stdout_may_close():
                print(maps.point_line(point.index, len(self.cfg.map.studies), row), flush=True)

    def interrupted(self):
        """The point under way says where it stopped (its group's rank 0 writes)."""
        point = self.point
        if point is not None and not point.done and point.comm.rank == 0:
            results.write_status(point.cfg.output_dir, f"interrupted at level {len(point.levels)}")
        if self.comm.rank == 0:
            done = sum(point_status(c).startswith(ENDED) for c in self.cfg.map.studies)
            results.write_status(self.cfg.output_dir, f"interrupted ({done} of {len(self.cfg.map.studies)} "
                                                      "points done)")


def collect(cfg, known=None):
    """map.csv's rows, one per point: those `known` (point -> row), the others from the points' folders;
    a point not (yet) written, or written for another config, has its values and status alone."""
    rows = []
    for k, point in enumerate(cfg.map.studies):
        if known and k in known:
            rows.append(known[k])
            continue
        status = point_status(point)
        try:
            levels = resume.read_levels(point) if status else []
        except ConfigError:
            levels, status = [], "written for another config"
        rows.append(rate_map.row(point, cfg.map.values[k], levels, status or "not run", cfg.map.varied))
    return rows


def finish(cfg, draw=None, known=None):
    """map.csv, figures and tables from the rows `known` and the other points' folders, the map's status;
    the terminal summary."""
    rows = collect(cfg, known)
    with guard.writing(cfg.output_dir):
        written = maps.write(cfg.output_dir, rows, cfg.map.varied, draw=cfg.output.plots if draw is None else draw)
        done = sum(row["status"].startswith(ENDED) for row in rows)
        results.write_status(cfg.output_dir, "complete" if done == len(rows) else
                             f"partial ({done} of {len(rows)} points done)")
    return "\n".join([maps.summary(rows, cfg.map.varied, title=f"map {cfg.study}: {cfg.output_dir}"),
                      tables.wrote(path.name for path in written)])


def is_map(path):
    """Whether `path` is a map's folder (its config says study_type: map)."""
    path = Path(path) / CONFIG_FILE
    return path.is_file() and "study_type: map" in path.read_text()


def report(folder, draw=True):
    """Redraw a map from its folder: its config, the points' folders; the terminal summary."""
    folder = Path(folder).resolve()
    cfg = config.loads((folder / CONFIG_FILE).read_text(), [f"output.dir={folder.parent}", f"study={folder.name}"])
    return finish(cfg, draw)
