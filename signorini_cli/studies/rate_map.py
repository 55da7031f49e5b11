"""The rate map (study_type: map): one refinement study per point of a grid of config values, run in one
process (modules loaded once, each distinct form compiled once, each mesh built and its data checked
once), the points taken in turn by groups of MPI ranks as they come free; and a point's row of map.csv."""
import logging
from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI

from ..analysis import verdict
from ..config import ConfigError
from ..meshing import meshes
from ..problems import registry
from ..solve import solver
from . import jit_cache
from . import refinement

logger = logging.getLogger(__name__)

NORMS = ("L2", "H1")  # first, in this order; any other measured norm follows
NORM_COLUMNS = ("rate_{}", "rate_{}_lo", "rate_{}_hi", "rate_{}_log", "proven_{}", "verdict_{}", "{}")
TAIL_COLUMNS = ("converged", "newton_its", "time_s", "status")

NAME = "map"
UNIT = "points"  # what status.txt counts
RESUMABLE = False  # --resume of a map: app/maps solves the points not yet ended
POINTS = True  # each point a refinement study of its own, run and recorded by app/maps


@dataclass
class Point:
    """One point of a map while it runs: its number, values and config, the group of ranks solving it,
    its levels so far; `failure` says why it ended early (an exception), `done` once it has ended."""
    index: int
    values: dict
    cfg: object
    comm: object
    levels: list = field(default_factory=list)
    failure: str = ""
    done: bool = False
    before: list = field(default_factory=list)  # the levels an earlier run solved: the point goes on after them
    taken: bool = True  # False: on_level left the point to another run (a chunk of the same map writes it)

    @property
    def outcome(self):
        """The point's study as one outcome (the Study of a map says whether every point converged): converged
        when it ended without an exception and every level converged, with the Newton iterations of all."""
        converged = (self.done and not self.failure and bool(self.levels)
                     and all(lv.outcome.converged for lv in self.levels))
        return solver.Outcome(converged, self.failure or ("CONVERGED" if converged else "NOT_CONVERGED"),
                              sum(lv.outcome.newton_its for lv in self.levels),
                              sum(lv.outcome.linear_its for lv in self.levels), ())


def group_count(size, ranks_per_point):
    """How many groups of ranks_per_point ranks `size` ranks make; ConfigError unless it divides them."""
    if size % ranks_per_point:
        raise ConfigError("map.ranks_per_point", f"must divide the {size} MPI ranks, got {ranks_per_point}")
    return size // ranks_per_point


def groups(comm, ranks_per_point):
    """(group communicator, how many groups): comm split into blocks of consecutive ranks."""
    count = group_count(comm.size, ranks_per_point)
    return comm.Split(comm.rank // ranks_per_point, comm.rank), count


class Dispenser:
    """The points to run, taken one at a time by the groups as they come free: a counter on COMM_WORLD's
    rank 0 that each group's rank 0 fetches and adds to (MPI one-sided, no reply from rank 0 awaited; with
    Open MPI's osc pt2pt a take may wait for rank 0's next MPI call), so a group slowed by its points or its
    node takes fewer. A point's numbers do not depend on its group: any group solves it the same way."""

    def __init__(self, todo, comm, group, count):
        self.todo, self.group = list(todo), group
        self.next = 0  # one group: the points in order, no counter
        self.window = MPI.Win.Allocate(8 if comm.rank == 0 else 0, 8, comm=comm) if count > 1 else None
        if self.window is not None:
            if comm.rank == 0:
                self.window.Lock(0, MPI.LOCK_EXCLUSIVE)
                self.window.Put(np.zeros(1, dtype=np.int64), 0)
                self.window.Unlock(0)
            comm.Barrier()

    def __iter__(self):
        while (k := self.take()) < len(self.todo):
            yield self.todo[k]
        self.free()

    def take(self):
        """The next place in todo: fetched by the group's rank 0, which tells the others."""
        if self.window is None:
            self.next += 1
            return self.next - 1
        got = np.zeros(1, dtype=np.int64)
        if self.group.rank == 0:
            self.window.Lock(0, MPI.LOCK_SHARED)
            self.window.Fetch_and_op(np.ones(1, dtype=np.int64), got, 0, 0, MPI.SUM)
            self.window.Unlock(0)
        return self.group.bcast(int(got[0]), root=0)

    def free(self):
        """Collective: every group ends here once the points are all taken."""
        if self.window is not None:
            self.window.Free()
            self.window = None


def run(cfg, on_level=None, comm=MPI.COMM_WORLD, monitor=None, done=()):
    """Run the points of cfg.map, each group of map.ranks_per_point ranks taking the next one as it comes
    free; `done`: the points not to run (finished, or outside the chunk asked for), or a mapping of point to
    None (not to run) or to the levels it has (it goes on after them). on_level(point) as a point starts,
    after each of its levels and as it ends (point.done). Returns the Points this group ran."""
    group, count = groups(comm, cfg.map.ranks_per_point)
    done = done if isinstance(done, dict) else dict.fromkeys(done)
    todo = [k for k in range(len(cfg.map.studies)) if done.get(k, []) is not None]
    with jit_cache.kept(), meshes.kept(), registry.checked_once():
        return [run_point(Point(k, cfg.map.values[k], cfg.map.studies[k], group, before=list(done.get(k) or [])),
                          on_level, monitor)
                for k in Dispenser(todo, comm, group, count)]


def run_point(point, on_level=None, monitor=None):
    """Solve the point's refinement study. A point whose solve raises is recorded with the reason and
    the map goes on; what on_level raises (the record could not be written, a signal) ends the map."""
    recording = []

    def record(levels=None):
        point.levels = point.levels if levels is None else levels
        if on_level is not None:
            try:
                on_level(point)
            except BaseException as err:
                recording.append(err)
                raise

    record(list(point.before))
    if not point.taken:
        return point
    try:
        point.levels = refinement.run(point.cfg, record, point.comm, monitor, done=point.before)
    except Exception as err:
        if recording and err is recording[-1]:
            raise
        point.failure = f"{type(err).__name__}: {(str(err).strip().splitlines() or [''])[0]}"
        logger.warning("map point %d failed: %s", point.index, point.failure)
    point.done = True
    record()
    return point


def columns(varied, norms):
    """map.csv's columns: the varied keys, seven per norm, then converged, Newton iterations, time, status."""
    return (tuple(varied) + tuple(c.format(n) for n in norms for c in NORM_COLUMNS) + TAIL_COLUMNS)


def norms_of(rows):
    """The norms of map.csv rows, L2 and H1 first."""
    found = [c[len("proven_"):] for row in rows for c in row if c.startswith("proven_")]
    found = list(dict.fromkeys(found))
    return [n for n in NORMS if n in found] + [n for n in found if n not in NORMS]


def row(cfg, values, levels, status, varied):
    """A point's row of map.csv: its values, per norm the fitted rate over the last levels with its
    interval, the log-corrected fit (the slope of e/|ln h|, where the proven rate carries |ln h|), the proven rate,
    the verdict
    and the finest converged error; whether every level converged, Newton iterations, wall time."""
    out = {key: values.get(key) for key in varied}
    for v in verdict.summarize(cfg, levels).norms if levels else ():
        finest = [lv.errors.get(v.norm) for lv in levels if lv.outcome.converged]
        out.update({f"rate_{v.norm}": v.observed, f"rate_{v.norm}_lo": v.lo, f"rate_{v.norm}_hi": v.hi,
                    f"rate_{v.norm}_log": v.log_corrected, f"proven_{v.norm}": v.proven,
                    f"verdict_{v.norm}": v.verdict, v.norm: finest[-1] if finest else None})
    out.update(converged=status == "complete" and all(lv.outcome.converged for lv in levels),
               newton_its=sum(lv.outcome.newton_its for lv in levels),
               time_s=sum(lv.time_s for lv in levels), status=status)
    return out
