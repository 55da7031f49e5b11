"""Faults around a study: SIGINT/SIGTERM end it cleanly, an exception on one rank ends every rank,
and the study's status is kept on disk next to its results."""
import logging
import os
import signal
import sys
import time
import traceback
from contextlib import contextmanager

from mpi4py import MPI

from . import results

logger = logging.getLogger(__name__)

SIGNALS = (signal.SIGINT, signal.SIGTERM)
# A rank other than 0 waits this long before it reports a fault: when rank 0 has the same fault it
# reports it alone (its MPI abort ends the others first). Below Open MPI's 1 s between the SIGTERM
# mpirun forwards on Ctrl-C and its SIGKILL.
GRACE_S = 0.5
# Testing hook, documented in README: SIGNORINI_TEST_FAIL=RANK:LEVEL makes that rank raise as that
# level starts, like a crash inside a level (tests/test_guard.py: one rank of two fails).
TEST_FAIL = "SIGNORINI_TEST_FAIL"
CRASH_STATUS = 3  # a bug (an exception that is no bad input): its traceback is printed, the status kept


class Interrupted(BaseException):
    """SIGINT or SIGTERM arrived. A BaseException, as KeyboardInterrupt: `except Exception` lets it by."""

    def __init__(self, signum):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum
        self.note = ""  # where the study stood, added by Watch

    @property
    def exit_status(self):
        return 128 + self.signum  # the shell's convention: 130 for SIGINT, 143 for SIGTERM


class _Signals:
    """The handler: raise Interrupted, or hold the signal back while results are being written."""

    def __init__(self):
        self.holding, self.pending = 0, None

    def handle(self, signum, frame):
        if self.holding:
            self.pending = signum
        else:
            raise Interrupted(signum)


_signals = _Signals()


@contextmanager
def interruptible():
    """Within: SIGINT and SIGTERM raise Interrupted (between Python statements, so also inside
    PETSc's callbacks); the previous handlers are restored after."""
    try:
        previous = {sig: signal.signal(sig, _signals.handle) for sig in SIGNALS}
    except ValueError:  # not the main thread: signals stay as they are
        previous = {}
    try:
        yield
    finally:
        with deferred(drop=True):  # a signal now would escape as a traceback
            for sig, handler in previous.items():
                signal.signal(sig, handler)


@contextmanager
def deferred(drop=False):
    """Within: a signal waits until the block is done, then raises (a level is written whole);
    drop=True forgets it instead (the study is already ending)."""
    _signals.holding += 1
    try:
        yield
    finally:  # with an exception on its way out, a held signal is dropped: the study is ending anyway
        _signals.holding -= 1
        signum = None if _signals.holding else _signals.pending
        _signals.pending = _signals.pending if _signals.holding else None
    if signum is not None and not drop:
        raise Interrupted(signum)


def supervise(body):
    """body() -> exit status, with SIGINT/SIGTERM as Interrupted. An interruption prints one line and
    gives 128 + signal. On several ranks any fault ends every rank (MPI abort) instead of leaving the
    others waiting in a collective; a bug's traceback is printed once."""
    comm = MPI.COMM_WORLD
    with interruptible():
        try:
            return body()
        except Interrupted as sig:
            settle(sig, comm)
            if comm.rank == 0:  # mpirun passes Ctrl-C on to every rank: one line, not one per rank
                print(f"signorini: interrupted by {sig}{sig.note}", file=sys.stderr)
            _abort_if_parallel(comm, sig.exit_status)
            return sig.exit_status
        except Exception as err:
            if comm.size > 1:
                settle(err, comm)
                traceback.print_exc()
                print(f"signorini: rank {comm.rank} failed: {_first_line(err)}; aborting all {comm.size} ranks",
                      file=sys.stderr)
                _abort_if_parallel(comm, CRASH_STATUS)
            raise


def settle(err, comm):
    """Wait GRACE_S on ranks other than 0, once per fault (see GRACE_S)."""
    if comm.rank != 0 and not getattr(err, "signorini_settled", False):
        time.sleep(GRACE_S)
    err.signorini_settled = True


def _abort_if_parallel(comm, status):
    if comm.size > 1:
        sys.stdout.flush()
        sys.stderr.flush()
        comm.Abort(status)


def _first_line(err):
    text = str(err).strip().splitlines()
    return f"{type(err).__name__}: {text[0]}" if text else type(err).__name__


def status(cfg, result):
    """'complete'; 'failed at level k: REASON' when a level did not converge and on_failure is stop;
    else 'running (k of n levels done)' (for the ε → 0 studies: solves, not levels)."""
    solves = list(result)
    unit = "levels" if cfg.study_type in results.LEVEL_STUDIES else "solves"
    last = solves[-1] if solves else None
    if unit == "levels" and last and not last.outcome.converged and cfg.solver.on_failure == "stop":
        return f"failed at level {last.index}: {last.outcome.reason}"
    if len(solves) == cfg.solves:
        return "complete"
    return f"running ({len(solves)} of {cfg.solves} {unit} done)"


class Watch:
    """Keeps a study's record current: rates.csv, study.h5 and status.txt at the start, after every
    level, and when it ends: complete, failed at level k: reason, interrupted at level k."""

    def __init__(self, cfg, done, comm):
        self.cfg, self.levels, self.comm = cfg, list(done), comm
        self.done = self.recorded = len(done)

    def __enter__(self):
        try:
            self.level_done(self.levels)  # a forced rerun replaces the old results at once
        except BaseException as err:  # __exit__ is not called when __enter__ fails: record, then go on
            self.__exit__(type(err), err, err.__traceback__)
            raise
        return self

    def level_done(self, levels):
        """run_study's on_level: write the results whole (signals wait), then the testing hook; the rows."""
        with deferred():
            self.levels = list(levels) if isinstance(levels, list) else levels  # a Sweep, Total: as it grows
            start = time.perf_counter()
            rows = results_write(self.cfg, self.levels, self.comm)
            if isinstance(self.levels, list) and len(self.levels) > self.recorded:  # the new level's t_output
                timings = self.levels[-1].timings
                timings["t_output"] = timings.get("t_output", 0.0) + time.perf_counter() - start
                self.recorded = len(self.levels)
        fault_hook(len(list(self.levels)), self.comm)
        return rows

    def __exit__(self, kind, err, tb):
        if err is None and len(list(self.levels)) > self.done:
            with deferred():  # once more, so that the last level's record holds its own t_output
                results_write(self.cfg, self.levels, self.comm)
            return False
        if err is None or not isinstance(err, (Exception, Interrupted)):
            return False
        settle(err, self.comm)
        state = self.ending(err)
        if isinstance(err, Interrupted):
            done = len(list(self.levels))
            err.note = (f" at level {done}: the {done} finished level(s) are in "
                        f"{self.cfg.output_dir}; continue with --resume" if state.startswith("interrupted")
                        else f" as the study ended ({state}): results in {self.cfg.output_dir}")
        with deferred(drop=True):
            self.record(state)
        return False

    def ending(self, err):
        """The status a study ending with `err` leaves."""
        if status(self.cfg, self.levels).startswith("running"):
            where = f"at level {len(list(self.levels))}"
            if isinstance(err, Interrupted):
                return f"interrupted {where}"
            return f"failed {where}: {_first_line(err)}"
        return status(self.cfg, self.levels)  # every level was done when it came

    def record(self, state):
        """Write the results with `state` from this rank alone: the others may be gone or waiting."""
        try:
            rows = results.main_table(self.cfg, self.levels)
            results.write_files(self.cfg, self.levels, rows, self.comm.size, state)
        except OSError as err:
            logger.warning("could not record the status %r in %s: %s", state, self.cfg.output_dir, err)


def results_write(cfg, levels, comm):
    """rates.csv, study.h5 and status.txt of the levels so far (collective); the table's rows."""
    return results.write(cfg, levels, comm, status=status(cfg, levels))


def fault_hook(level, comm):
    """Testing hook: with SIGNORINI_TEST_FAIL=RANK:LEVEL set, that rank raises as that level starts."""
    spec = os.environ.get(TEST_FAIL)
    if spec and spec == f"{comm.rank}:{level}":
        raise RuntimeError(f"{TEST_FAIL}={spec}: rank {comm.rank} fails at the start of level {level}")
