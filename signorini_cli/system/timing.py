"""Where a level's time goes: wall time per phase and peak memory, for error-against-cost."""
import resource
import time
from contextlib import contextmanager

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

# a level's phases, in table order; `linear` and `pc_setup` come from PETSc's event log, the rest
# are wall clocks (transfer: the initial guess, nested iteration's move of the previous level's u_h;
# newton: the SNES solves; contact: the Γ_C terms integrated beside UFL, a part of the two assemblies).
# PETSc logs KSPSolve without the PCSetUp it triggers first (the LU factorisation or the AMG set-up), so
# linear = KSPSolve + PCSetUp, and pc_setup is that part of it.
PHASES = ("mesh", "forms", "transfer", "assemble_residual", "assemble_jacobian", "contact", "linear", "pc_setup",
          "newton", "errors", "output")
PETSC_EVENTS = {"linear": ("KSPSolve", "PCSetUp"), "pc_setup": ("PCSetUp",)}


class Phases:
    """Seconds spent per phase of one level, summed over every time the phase is entered."""

    def __init__(self):
        self.seconds = dict.fromkeys(PHASES, 0.0)

    @contextmanager
    def __call__(self, name):
        """Time the block as phase `name`; with name 'newton', also PETSc's linear-solve events."""
        start, events = time.perf_counter(), petsc_event_times() if name == "newton" else None
        try:
            yield
        finally:
            self.seconds[name] += time.perf_counter() - start
            if events is not None:
                for phase, spent in petsc_event_times().items():
                    self.seconds[phase] += spent - events[phase]

    def deduct(self, name, seconds):
        """Take back out of phase `name` the seconds of work inside it that is reported elsewhere."""
        self.seconds[name] -= seconds

    def columns(self, comm):
        """{'t_<phase>': seconds}, each the largest over ranks (wall time: the slowest rank sets it)."""
        local = np.array([self.seconds[name] for name in PHASES])
        slowest = np.empty_like(local)
        comm.Allreduce(local, slowest, op=MPI.MAX)
        return {f"t_{name}": float(value) for name, value in zip(PHASES, slowest)}


def petsc_event_times():
    """Seconds PETSc has logged so far on this rank in the events of PETSC_EVENTS (the log is
    switched on at the first call: a phase that starts it counts from there)."""
    if not PETSc.Log.isActive():
        PETSc.Log.begin()
    return {phase: sum(PETSc.Log.Event(event).getPerfInfo()["time"] for event in events)
            for phase, events in PETSC_EVENTS.items()}


def peak_memory_mb(comm):
    """The largest peak resident set size of any rank so far, in MiB (ru_maxrss is in KiB on Linux)."""
    return comm.allreduce(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, op=MPI.MAX)
