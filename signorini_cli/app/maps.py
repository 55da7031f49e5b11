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
from ..system import files
from . import checks, guard

ENDED = ("complete", "failed")  # a point whose status.txt starts so has ended: --resume keeps it
CONFIG_FILE = "config.yaml"  # the resolved config, beside a map's and every point's results
ROOT_VARIABLES = ("OMPI_ALLOW_RUN_AS_ROOT", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM")
OVERSUBSCRIBE = "OMPI_MCA_rmaps_base_oversubscribe"


def relaunch(jobs):
    """map.jobs > 1 on one process: the same command again under `mpirun -n jobs`, one point per rank
    (this process is replaced; its folder lock ends with it and the new rank 0 takes it)."""
    mpirun = shutil.which("mpirun")
    if mpirun is None:
        raise ConfigError("map.jobs", f"{jobs} workers run under mpirun, which is not on PATH; run the map "
                                      "under mpirun -n N yourself, or set map.jobs: 1")
    cpus = len(os.sched_getaffinity(0))
    if jobs > cpus:
        raise ConfigError("map.jobs", f"{jobs} workers, but this process may use {cpus} CPUs; set map.jobs <= "
                                      f"{cpus}, or run the map under mpirun -n N yourself")
    sys.stdout.flush()
    # os.environ is the environment this process started with: MPI's start-up added variables of its own
    # to the C environment that would make mpirun take the new job for this one
    env = dict(os.environ)
    if os.geteuid() == 0:  # Open MPI's mpirun refuses root (a 13-line banner, exit 1) unless told twice
        env.update({name: env.get(name, "1") for name in ROOT_VARIABLES})
    # Open MPI counts a slot per core, not per hardware thread: up to the CPUs this process may use are fine
    env.setdefault(OVERSUBSCRIBE, "1")
    # -q: no Open MPI banner after a rank's exit status 2 or 1: the ranks said it in one line
    os.execve(mpirun, [mpirun, "-q", "-n", str(jobs), *sys.orig_argv], env)


# who may write a map folder at once: the refusal's line says it
BUSY = ("; a whole run of a map writes its folder alone, while chunks (--points) of one map may run together; "
        "wait for it to end or choose another output folder")


def run(cfg, points=None, force=False, resume_map=False, quiet=False, memory=True, comm=MPI.COMM_WORLD,
        on_level=None):
    """Run the map's points (those of the chunk `points`, e.g. "0-49", else all; with resume_map those not
    yet ended, a point with fewer levels than its config asks for going on after them), then write map.csv,
    figures and tables on rank 0. Every point passes a single study's checks before any is solved. A whole
    run holds the map folder alone, a chunk shares it with other chunks and takes its points one by one.
    on_level(point) after each level of a point too. Returns the Points this group ran."""
    count = len(cfg.map.studies)
    chosen = map_config.chunk(points, count) if points is not None else list(range(count))
    checks.map_points(cfg, chosen, comm, memory, rate_map.group_count(comm.size, cfg.map.ranks_per_point))
    with guard.FolderLock(cfg.output_dir, comm, shared=points is not None, busy=BUSY):
        return _run_held(cfg, chosen, points is not None, force, resume_map, quiet, comm, on_level)


def exit_status(ran, comm):
    """0 when every point run (on any rank) converged, else 1 (collective)."""
    ok = all(p.outcome.converged for p in ran if p.taken)
    return 0 if comm.allreduce(ok, op=MPI.LAND) else 1


def _run_held(cfg, chosen, chunked, force, resume_map, quiet, comm, on_level):
    """run(), once the map folder is held."""
    count = len(cfg.map.studies)
    found, done = resume.on_rank_zero(comm, lambda: _found(cfg, chosen, chunked, force, resume_map))
    if comm.rank == 0:
        if force and not chunked:
            start_over(cfg)
        _start(cfg, count, sum(levels is None for k, levels in done.items() if k in chosen))
    recorder = Recorder(cfg, comm, quiet, found if chunked else None, on_level)
    skipped = dict.fromkeys(set(range(count)) - set(chosen))
    try:
        ran = studies.run_study(cfg, on_level=recorder, comm=comm, done={**done, **skipped})
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
    return ran


def point_status(cfg):
    """A point folder's status.txt line ('' when absent)."""
    return results.read_status(cfg.output_dir)


def status_of(point):
    """The status line of a point that has ended, as its folder's status.txt says it."""
    if point.failure:
        return f"failed at level {len(point.levels)}: {point.failure}"
    return guard.status(point.cfg, point.levels)


def _found(cfg, chosen, chunked, force, resume_map):
    """({point: its status.txt line} of the chosen points, {point: None when it has ended, else the levels
    it goes on after} with resume_map), after refusing to overwrite results unless asked."""
    found = {k: point_status(cfg.map.studies[k]) for k in chosen}
    if not (force or resume_map):
        _check_fresh(cfg, [k for k in chosen if found[k]], whole=not chunked)
    return found, ({k: _continued(cfg.map.studies[k], found[k]) for k in chosen} if resume_map else {})


def _continued(point, status):
    """None when the point has ended (complete with every level of its config, or failed), else the levels
    of its study.h5 it goes on after; ConfigError naming the keys when its config changed otherwise."""
    levels = resume.read_levels(point)
    if status.startswith(ENDED) and not (status.startswith("complete") and len(levels) < point.solves):
        return None
    return levels


def _check_fresh(cfg, held, whole):
    """Refuse to overwrite results unless asked: the map's map.csv (whole runs) and the chosen points'."""
    held = [Path(cfg.map.studies[k].output_dir) for k in held]
    if whole and (Path(cfg.output_dir) / maps.MAP_FILE).exists():
        held.insert(0, Path(cfg.output_dir))
    if held:
        raise ConfigError("output.dir", f"{held[0]} already holds results; use --resume to continue them or "
                                        "--force to overwrite")


def start_over(cfg):
    """--force on a whole map: the map's tables and figures and every point's results are removed (only
    the files a run writes), so none of an earlier, larger grid stays beside the new map."""
    results.start_over(cfg.output_dir)
    points = map_config.folder_of(cfg)
    for folder in (points.iterdir() if points.is_dir() else ()):
        if folder.is_dir() and folder.name.isdigit():
            results.start_over(folder, also=(CONFIG_FILE,))
            if not any(folder.iterdir()):
                folder.rmdir()


def _start(cfg, count, ended):
    """The map's own config and status, and its points' folder, written as it starts."""
    folder = Path(cfg.output_dir)
    map_config.folder_of(cfg).mkdir(parents=True, exist_ok=True)
    files.replace(folder / CONFIG_FILE, lambda path: path.write_text(config.yaml_dump(config.to_dict(cfg))))
    results.write_status(folder, f"running ({ended} of {count} points done)")


class Recorder:
    """on_level of a map: a point's folder prepared as the point starts and its results written once as it
    ends (its group's rank 0 writes; signals wait): a finished point is kept whole, one under way is
    solved again by --resume. A line per finished point; `rows`, map.csv's rows of the points this
    group's rank 0 finished (the same as read back from their folders). A chunk's recorder (`found`: the
    status lines of its points as it started) locks each point as it starts and leaves to its run a point
    that another chunk writes or has written since."""

    def __init__(self, cfg, comm, quiet, found=None, on_level=None):
        self.cfg, self.comm, self.quiet, self.found, self.on_level = cfg, comm, quiet, found, on_level
        self.point, self.lock, self.rows = None, None, {}

    def __call__(self, point):
        if point is not self.point:
            self.begin(point)
        if not point.taken:
            return
        if not point.done:
            if self.on_level is not None and len(point.levels) > len(point.before):
                self.on_level(point)
            return
        with guard.deferred():
            guard.results_write(studies.study_of(point.cfg, point.levels), point.comm)
            if point.failure and point.comm.rank == 0:
                results.write_status(point.cfg.output_dir, status_of(point))
        self.end(point)

    def begin(self, point):
        """A point's folder: locked (a chunk's points), emptied of an earlier run's files unless the point
        goes on after its levels, its resolved config beside it."""
        self.point = point
        if self.found is not None:
            point.taken = self.claim(point)
            if not point.taken:
                return
        if point.comm.rank == 0:
            folder = Path(point.cfg.output_dir)
            folder.mkdir(parents=True, exist_ok=True)
            for path in folder.iterdir() if not point.before else ():
                if path.is_file():
                    path.unlink()
            files.replace(folder / CONFIG_FILE, lambda path: path.write_text(point.cfg.text))
            results.write_status(folder, "running")
        point.comm.barrier()

    def claim(self, point):
        """Whether this chunk writes the point: it holds the point's lock and the point's status is still
        the one this chunk started from (the group's rank 0 decides)."""
        if point.comm.rank == 0:
            self.lock = guard.try_lock(point.cfg.output_dir)
            if self.lock is not None and point_status(point.cfg) != self.found[point.index]:
                self.release()
        return point.comm.bcast(self.lock is not None, root=0)

    def release(self):
        if self.lock is not None:
            os.close(self.lock)  # closing the descriptor drops the flock
            self.lock = None

    def end(self, point):
        self.release()
        if point.comm.rank != 0:
            return
        row = rate_map.row(point.cfg, point.values, point.levels, status_of(point), self.cfg.map.varied)
        self.rows[point.index] = row
        if not self.quiet:
            with guard.stdout_may_close():
                print(maps.point_line(point.index, len(self.cfg.map.studies), row), flush=True)

    def interrupted(self):
        """The point under way says where it stopped (its group's rank 0 writes)."""
        point = self.point
        if point is not None and point.taken and not point.done and point.comm.rank == 0:
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


def finish(cfg, draw=None, known=None, into=None):
    """map.csv, figures and tables from the rows `known` and the other points' folders, written into `into`
    (a report elsewhere), else into the map's folder with the map's status: there one run or report at a
    time reads the points and writes, so the last to finish sees every point that ended; the terminal
    summary."""
    draw = cfg.output.plots if draw is None else draw
    if into is not None:
        return _write(cfg, Path(into), collect(cfg, known), draw)
    with guard.held(map_config.folder_of(cfg)):
        rows = collect(cfg, known)
        text = _write(cfg, Path(cfg.output_dir), rows, draw)
        done = sum(row["status"].startswith(ENDED) for row in rows)
        with guard.writing(cfg.output_dir):
            results.write_status(cfg.output_dir, "complete" if done == len(rows) else
                                 f"partial ({done} of {len(rows)} points done)")
    return text


def _write(cfg, folder, rows, draw):
    """The map's files from its rows in `folder`; the terminal summary."""
    with guard.writing(folder):
        folder.mkdir(parents=True, exist_ok=True)
        written = maps.write(folder, rows, cfg.map.varied, draw=draw)
    elsewhere = folder if folder != Path(cfg.output_dir) else None
    return "\n".join([maps.summary(rows, cfg.map.varied, title=f"map {cfg.study}: {cfg.output_dir}"),
                      tables.wrote((path.name for path in written), elsewhere)])


def is_map(path):
    """Whether `path` is a map's folder (its config says study_type: map)."""
    path = Path(path) / CONFIG_FILE
    return path.is_file() and "study_type: map" in path.read_text()


def report(folder, draw=True, into=None):
    """Redraw a map from its folder (into the folder `into` instead when given): its config, the points'
    folders; the terminal summary."""
    folder = Path(folder).resolve()
    cfg = config.loads((folder / CONFIG_FILE).read_text(), [f"output.dir={folder.parent}", f"study={folder.name}"])
    return finish(cfg, draw, into=into)
