"""The study types by name: each runs its levels and returns the solves (no printing, no files)."""
from mpi4py import MPI

from .map import run_map
from .refinement import run_refinement
from .signorini import run_signorini
from .sweep import run_sweep
from .total import run_total

STUDY_TYPES = {"refinement": run_refinement, "signorini": run_signorini, "epsilon_sweep": run_sweep,
               "total_error": run_total, "map": run_map}


def run_study(cfg, on_level=None, comm=MPI.COMM_WORLD, monitor=None, done=()):
    """Run the study of type cfg.study_type; call on_level(result_so_far) after every solve; return
    the result: a list of Levels (refinement, signorini), a Sweep or a Total.
    `monitor(snes, its, fnorm)`, if given, is called at every Newton iteration (progress).
    `done`: the levels a resumed refinement study already has, kept as they are and not solved again."""
    return STUDY_TYPES[cfg.study_type](cfg, on_level, comm, monitor, done)
