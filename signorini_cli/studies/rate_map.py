"""The rate map (study_type: map): one refinement study per point of a grid of config values, run in one
process (modules loaded once, each distinct form compiled once, each mesh built and its data checked
once), the points shared out among groups of MPI ranks; and a point's row of map.csv."""
import logging
from dataclasses import dataclass, field

from mpi4py import MPI

from ..analysis import verdict
from ..config import ConfigError
from ..meshing import meshes
from ..problems import registry
from . import jit_cache
from . import refinement

logger = logging.getLogger(__name__)

NORMS = ("L2", "H1")  # first, in this order; any other measured norm follows
NORM_COLUMNS = ("rate_{}", "rate_{}_lo", "rate_{}_hi", "rate_{}_plain", "proven_{}", "verdict_{}", "{}")
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


def groups(comm, ranks_per_point):
    """(group communicator, its number, how many groups): comm split into blocks of consecutive ranks."""
    if comm.size % ranks_per_point:
        raise ConfigError("map.ranks_per_point", f"must divide the {comm.size} MPI ranks, got {ranks_per_point}")
    color = comm.rank // ranks_per_point
    return comm.Split(color, comm.rank), color, comm.size // ranks_per_point


def assigned(indices, color, count):
    """The points group `color` of `count` runs: every count-th from its own place. Fixed by the indices
    alone, so a chunk of a map runs the same points on the same group every time."""
    return list(indices)[color::count]


def run(cfg, on_level=None, comm=MPI.COMM_WORLD, monitor=None, done=()):
    """Run the points of cfg.map not in `done` (finished, or outside the chunk asked for), each group of
    map.ranks_per_point ranks its share in turn; on_level(point) as a point starts, after each of its
    levels and as it ends (point.done). Returns the Points this group ran."""
    group, color, count = groups(comm, cfg.map.ranks_per_point)
    skipped = set(done)
    todo = [k for k in range(len(cfg.map.studies)) if k not in skipped]
    with jit_cache.kept(), meshes.kept(), registry.checked_once():
        return [run_point(Point(k, cfg.map.values[k], cfg.map.studies[k], group), on_level, monitor)
                for k in assigned(todo, color, count)]


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

    record()
    try:
        point.levels = refinement.run(point.cfg, record, point.comm, monitor)
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
    interval, the plain fit (differs when the proven rate carries |ln h|), the proven rate, the verdict
    and the finest converged error; whether every level converged, Newton iterations, wall time."""
    out = {key: values.get(key) for key in varied}
    for v in verdict.summarize(cfg, levels).norms if levels else ():
        finest = [lv.errors.get(v.norm) for lv in levels if lv.outcome.converged]
        out.update({f"rate_{v.norm}": v.observed, f"rate_{v.norm}_lo": v.lo, f"rate_{v.norm}_hi": v.hi,
                    f"rate_{v.norm}_plain": getattr(v, "plain", v.observed), f"proven_{v.norm}": v.proven,
                    f"verdict_{v.norm}": v.verdict, v.norm: finest[-1] if finest else None})
    out.update(converged=status == "complete" and all(lv.outcome.converged for lv in levels),
               newton_its=sum(lv.outcome.newton_its for lv in levels),
               time_s=sum(lv.time_s for lv in levels), status=status)
    return out
