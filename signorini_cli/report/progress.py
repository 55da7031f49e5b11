"""Progress of a running study on rank 0: a line per finished level, Newton steps of long levels, and
the time left once the levels' costs allow an honest estimate."""
import sys
import time

from ..analysis import rates
from ..config import MESH_KINDS
from .tables import TERMINAL_WIDTH, norms

NEWTON_AFTER_S = 3.0  # a level running longer than this shows its Newton iterations as they come
ETA_LEVELS = 3        # cost ~ dofs^p is fitted over the last 3 levels
MIN_EXPONENT = 1.0    # no solver is cheaper than linear in dofs: coarse levels (JIT, set-up) fit below 1
MAX_EXPONENT = 1.5    # the recorded studies (bench/results.csv) scale with p <= 1.2; noise fits above 1.5
FLOOR_FACTOR = 3.0    # a level's cost tells the scaling once it is 3x the cheapest level's


class Progress:
    """Prints to `stream` (stderr) if `show` (rank 0, not --quiet); `level_done(rows)` after each level,
    `monitor` is a SNES monitor."""

    def __init__(self, cfg, show=True, stream=None, newton_after=NEWTON_AFTER_S, clock=time.perf_counter):
        self.refinements, self.dim = cfg.mesh.levels, cfg.dimension
        self.mesh = cfg.mesh
        self.show = show
        self.stream = stream or sys.stderr
        self.newton_after, self.clock = newton_after, clock
        self.level, self.started = 0, clock()

    def level_done(self, rows):
        """Print the line of the level just finished (the last row) with the time left for the others."""
        self.level, self.started = len(rows), self.clock()
        if self.show:
            eta = remaining_time(rows, *levels_left(self.mesh, rows, self.dim))
            self._print(with_time_left(level_line(rows[-1]), eta))

    def monitor(self, snes, its, fnorm):
        """SNES monitor: once the level has run NEWTON_AFTER_S, one line per Newton iteration."""
        elapsed = self.clock() - self.started
        if self.show and elapsed > self.newton_after:
            n = self.refinements[self.level] if self.level < len(self.refinements) else "?"
            label = f"N={n}" if self.mesh.kind in MESH_KINDS else f"{self.mesh.level_key}: {n}"
            self._print(f"  level {self.level} ({label}): Newton iteration {its}, "
                        f"|F| = {fnorm:.3e}  ({format_duration(elapsed)})")

    def _print(self, line):
        print(line, file=self.stream, flush=True)


SHOWN_NORMS = 2  # L2 and H1 (or their _ref twins): a line stays within TERMINAL_WIDTH columns


def level_line(row):
    """level, N, dofs, eps, Newton iterations, the first two errors with rates, time: one line."""
    parts = [f"level {row['level']}", f"N={row['N']}", f"dofs={row['dofs']}", f"eps={row['epsilon']:.3e}"]
    if row["converged"]:
        parts.append(f"newton {row['newton_its']}")
    else:
        parts.append(f"NOT CONVERGED after {row['newton_its']} ({row['reason']})")
    for norm in norms([row])[:SHOWN_NORMS]:  # the rest are in the table at the end and in rates.csv
        if row.get(norm) is not None:
            rate = row[f"rate_{norm}"]
            parts.append(f"{norm} {row[norm]:.3e}" + (f" (rate {rate:.2f})" if rate is not None else ""))
    parts.append(format_duration(row["time_s"]))
    return "  ".join(parts)


def with_time_left(line, eta):
    """The level's line and the time left (if estimated): on the line while it stays within TERMINAL_WIDTH,
    else on a line of its own below."""
    if not eta:
        return line
    left = f"~{format_duration(eta)} left"
    return f"{line}  {left}" if len(line) + 2 + len(left) <= TERMINAL_WIDTH else f"{line}\n  {left}"


def levels_left(mesh, rows, dim):
    """(N of the levels still to come, dimension) for remaining_time. gmsh/file meshes have N = cells, so
    their coming levels' cells are predicted from the last level's (cells ~ size^-d, or 2^d times per
    refinement) with dimension 1; a list of .msh files predicts nothing."""
    done = len(rows)
    if mesh.kind in MESH_KINDS:
        return mesh.refinements[done:], dim
    if mesh.refine == "uniform":
        growth = [2.0 ** (dim * (k - mesh.refinements[done - 1])) for k in mesh.refinements[done:]]
    elif mesh.kind == "gmsh":
        growth = [(mesh.sizes[done - 1] / size) ** dim for size in mesh.sizes[done:]]
    else:
        return (), dim
    return tuple(rows[-1]["N"] * g for g in growth), 1


def remaining_time(rows, refinements_left, dim):
    """Seconds the levels still to come will take, or None until an estimate can be honest: from
    cost ~ dofs^p over the levels whose cost is clearly above the set-up floor (level_costs), their dofs
    estimated as dofs ~ N^dim. None when nothing is left."""
    if not refinements_left or not rows:
        return None
    points = scaling_levels(rows)
    if not points:
        return None
    dofs, seconds = zip(*points)
    p = cost_exponent(dofs, seconds)
    last = rows[-1]
    return sum(seconds[-1] * (last["dofs"] * (n / last["N"]) ** dim / dofs[-1]) ** p for n in refinements_left)


def level_costs(rows):
    """(dofs, seconds) of each level after the first, form compilation (t_forms) taken out: level 0
    holds the one-off costs (JIT compilation, first set-up) that the levels to come do not repeat."""
    return [(row["dofs"], row["time_s"] - (row.get("t_forms") or 0.0)) for row in rows[1:]
            if row.get("time_s") is not None]


def scaling_levels(rows):
    """The level_costs at least FLOOR_FACTOR times the cheapest: costs that grow with the dofs, not a
    fixed set-up floor (on the recorded studies estimates from them stay within 3x, tests/report/test_progress.py)."""
    costs = [(d, t) for d, t in level_costs(rows) if t > 0]
    if not costs:
        return []
    floor = min(t for _, t in costs)
    return [(d, t) for d, t in costs if t >= FLOOR_FACTOR * floor]


def cost_exponent(dofs, seconds, k=ETA_LEVELS):
    """Least-squares p in time ~ dofs^p over the last k levels, within [MIN_EXPONENT, MAX_EXPONENT]."""
    dofs, seconds = list(dofs[-k:]), list(seconds[-k:])
    p = rates.slope(dofs, seconds, k) if all(t > 0 for t in seconds) else None
    return MIN_EXPONENT if p is None else min(MAX_EXPONENT, max(MIN_EXPONENT, p))


def format_duration(seconds):
    """0.42 s, 12.3 s, 4 min 05 s, 2 h 03 min."""
    if seconds < 10:
        return f"{seconds:.2f} s"
    if seconds < 60:
        return f"{seconds:.1f} s"
    if seconds < 3600:
        minutes, s = divmod(int(round(seconds)), 60)
        return f"{minutes} min {s:02d} s"
    hours, minutes = divmod(int(round(seconds / 60)), 60)
    return f"{hours} h {minutes:02d} min"
