"""`signorini run` in which one rank raises as a given level starts, as a bug inside a level would:
`python failing_run.py RANK LEVEL run CONFIG ...` (the fault tests run it, also under mpirun)."""
import sys

from mpi4py import MPI

from signorini_cli.app import cli
from signorini_cli.studies import refinement


def failing(solve_level, rank, level):
    """solve_level, except that `rank` raises as level `level` starts."""
    def solve_or_fail(cfg, index, *args, **kwargs):
        if index == level and MPI.COMM_WORLD.rank == rank:
            raise RuntimeError(f"rank {rank} fails at the start of level {level}")
        return solve_level(cfg, index, *args, **kwargs)
    return solve_or_fail


if __name__ == "__main__":
    rank, level = int(sys.argv[1]), int(sys.argv[2])
    refinement.solve_level = failing(refinement.solve_level, rank, level)
    sys.argv = ["signorini"] + sys.argv[3:]
    sys.exit(cli.entry())
