"""Faults around a study: SIGINT/SIGTERM/SIGHUP end it cleanly, an exception on one rank ends every rank,
a study folder is written by one run at a time, output streams that fail end output quietly, a form
compilation is never cut short, and the study's status is kept on disk next to its results."""
import errno
import fcntl
import functools
import logging
import os
import signal
import sys
import time
import traceback
from contextlib import contextmanager
from pathlib import Path

from mpi4py import MPI

from ..config import ConfigError
from ..record import results, resume
from .. import studies
from ..system import errors, files

logger = logging.getLogger(__name__)

SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)  # SIGHUP: the terminal or the session went away
# A rank other than 0 waits this long before it reports a fault: when rank 0 has the same fault it
# reports it alone (its MPI abort ends the others first). Below Open MPI's 1 s between the SIGTERM
# mpirun forwards on Ctrl-C and its SIGKILL.
GRACE_S = 0.5
CRASH_STATUS = 3  # a bug (an exception that is no bad input): its traceback is printed, the status kept
BAD_SURROUNDINGS = 2  # as bad input: the results could not be written (a full disk, a folder gone read-only)


class Interrupted(BaseException):
    """SIGINT, SIGTERM or SIGHUP arrived. A BaseException, as KeyboardInterrupt: `except Exception` lets it by."""

    def __init__(self, signum):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum
        self.note = ""  # where the study stood, added by Watch

    @property
    def exit_status(self):
        return 128 + self.signum  # the shell's convention: 130 for SIGINT, 143 for SIGTERM, 129 for SIGHUP


class WriteFailed(Exception):
    """The study's files could not be written (OSError): the surroundings, not a bug. One line, exit 2."""

    def __init__(self, folder, err):
        super().__init__(f"{folder}: cannot write the results: {err.strerror or err}")
        self.reason = err.strerror or str(err)
        self.note = ""  # where the study stood, added by Watch


NO_ROOM = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS)  # the surroundings, not a bug


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


def _release():
    """Leave a block that held signals back; the held signal once the outermost block is left."""
    _signals.holding -= 1
    signum = None if _signals.holding else _signals.pending
    _signals.pending = _signals.pending if _signals.holding else None
    return signum


@contextmanager
def interruptible():
    """Within: SIGINT, SIGTERM and SIGHUP raise Interrupted (between Python statements, so also inside
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
        signum = _release()
    if signum is not None and not drop:
        raise Interrupted(signum)


def supervise(body):
    """body() -> exit status, with SIGINT/SIGTERM/SIGHUP as Interrupted. An interruption prints one line and
    gives 128 + signal. On several ranks any fault ends every rank (MPI abort) instead of leaving the
    others waiting in a collective; a bug's traceback is printed once."""
    comm = MPI.COMM_WORLD
    with interruptible(), compiling_whole():
        try:
            return body()
        except Interrupted as sig:
            with deferred(drop=True):  # a second signal (mpirun's SIGTERM to the ranks as one aborts) adds nothing
                settle(sig, comm)
                if comm.rank == 0:  # mpirun passes Ctrl-C on to every rank: one line, not one per rank
                    print(f"signorini: interrupted by {sig}{sig.note}", file=sys.stderr)
                _abort_if_parallel(comm, sig.exit_status)
            return sig.exit_status
        except WriteFailed as err:  # raised on the writer (rank 0; any rank for fields): it speaks, ends the others
            errors.print_error("", f"{err}{err.note}")
            _abort_if_parallel(comm, BAD_SURROUNDINGS)
            return BAD_SURROUNDINGS
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


def status(cfg, result, final=True):
    """'complete' ('complete: k of n levels converged' when some did not); 'failed at level k: REASON'
    when a level did not converge and on_failure is stop; else 'running (k of n levels done)' (for the ε → 0
    studies: solves, not levels), also with every level done while tables and figures are still being
    written (final=False)."""
    solves = list(result)
    unit = studies.of(cfg.study_type).UNIT
    last = solves[-1] if solves else None
    if unit == "levels" and last and not last.outcome.converged and cfg.solver.on_failure == "stop":
        return f"failed at level {last.index}: {last.outcome.reason}"
    if len(solves) == cfg.solves and final:
        failed = sum(not s.outcome.converged for s in solves)
        return "complete" if not failed else f"complete: {len(solves) - failed} of {len(solves)} {unit} converged"
    return f"running ({len(solves)} of {cfg.solves} {unit} done)"


class Watch:
    """Keeps a study's record current: rates.csv, study.h5 and status.txt at the start, after every
    level, and when it ends: complete (once tables and figures are written too), failed at level k:
    reason, interrupted at level k."""

    def __init__(self, cfg, done, comm):
        self.cfg, self.comm = cfg, comm
        self.study = studies.study_of(cfg, done)  # what is on disk
        self.done = self.recorded = len(done)

    def __enter__(self):
        try:
            self.level_done(self.study)  # a forced rerun replaces the old results at once
        except BaseException as err:  # __exit__ is not called when __enter__ fails: record, then go on
            self.__exit__(type(err), err, err.__traceback__)
            raise
        return self

    @property
    def levels(self):
        """The solves on disk: a level whose writing failed is not among them."""
        return self.study.result

    def level_done(self, study):
        """The runner's on_study: write the study whole (signals wait), then the testing hook; its rows.
        The new level's row gets the time its writing took (t_output), as the final record has it."""
        with deferred():
            start = time.perf_counter()
            rows = results_write(study, self.comm, final=False)
            with writing(self.cfg.output_dir):
                resume.keep_solution(self.cfg, study.result, self.comm)
            self.study = study
            if isinstance(study.result, list) and len(study.result) > self.recorded:  # the new level's t_output
                timings = study.result[-1].timings
                timings["t_output"] = timings.get("t_output", 0.0) + time.perf_counter() - start
                rows[-1]["t_output"] = timings["t_output"]
                self.recorded = len(study.result)
        return rows

    @property
    def solved(self):
        """The solves recorded so far (levels; an ε-sweep's or total-error study's solves)."""
        return len(list(self.levels))

    def finish(self, draw):
        """draw() (tables and figures, on rank 0) -> its result; status.txt says complete only after it."""
        with writing(self.cfg.output_dir):
            return draw() if self.comm.rank == 0 else None

    def __exit__(self, kind, err, tb):
        if err is None:
            with deferred():  # the final status, and the last level's record with its own t_output
                results_write(self.study, self.comm)
            return False
        if not isinstance(err, (Exception, Interrupted)):
            return False
        if isinstance(err, OSError) and err.errno in NO_ROOM:  # output.fields on a full disk: all ranks
            failed = WriteFailed(self.cfg.output_dir, err)
            self.__exit__(WriteFailed, failed, tb)
            raise failed from err
        with deferred(drop=True):  # the study is ending: a second signal adds nothing
            settle(err, self.comm)
            state = self.ending(err)
            if isinstance(err, Interrupted):
                err.note = self.note(state)
            elif isinstance(err, WriteFailed):
                err.note = f"; {state.split(':')[0]}:{self.note(state).split(':', 1)[1]}"
            self.record(state)
        return False

    def ending(self, err):
        """The status a study ending with `err` leaves."""
        if not status(self.cfg, self.levels, final=False).startswith("running"):
            return status(self.cfg, self.levels)  # stopped by on_failure: stop before it came
        k = self.solved
        where = (f"at level {k}" if k < self.cfg.solves
                 else f"while writing tables and figures (all {k} levels done)")
        if isinstance(err, Interrupted):
            return f"interrupted {where}"
        return f"failed {where}: {err.reason if isinstance(err, WriteFailed) else _first_line(err)}"

    def note(self, state):
        """What the one line on stderr adds: where the study stood and how to go on."""
        if state.startswith(("interrupted ", "failed ")):
            where = state.split(" ", 1)[1].split(":")[0]
            return (f" {where}: the {self.solved} finished level(s) are in {self.cfg.output_dir}; "
                    "continue with --resume")
        return f" as the study ended ({state}): results in {self.cfg.output_dir}"

    def record(self, state):
        """Write the results with `state` from this rank alone: the others may be gone or waiting. When
        they cannot be written (a full disk), status.txt alone, in place."""
        try:
            results.write_files(self.study, self.comm.size, state)
        except OSError as err:
            logger.debug("could not record the results in %s: %s", self.cfg.output_dir, err.strerror or err)
            try:
                results.write_status(self.cfg.output_dir, state)
            except OSError as again:
                logger.warning("could not record the status %r: %s", state, again.strerror or again)


def results_write(study, comm, final=True):
    """rates.csv, study.h5 and status.txt of a studies.Study (collective); the main table's rows.
    An OSError of the writer (rank 0) is a WriteFailed."""
    with writing(study.config.output_dir):
        return results.write(study, comm, status=status(study.config, study.result, final))


@contextmanager
def writing(folder):
    """Within: an OSError is a WriteFailed naming `folder` (a full disk is no bug)."""
    try:
        yield
    except OSError as err:
        raise WriteFailed(folder, err) from err


# --- one run per study folder --------------------------------------------------------------------

class FolderLock:
    """An exclusive flock on the study folder itself, held by rank 0 while a run writes it (shared=True: a
    shared one, which other shared holders may hold too, as a map's chunks do). The kernel drops it when the
    process ends, however it ends: a killed run leaves no stale lock. Folders made for it are removed again
    on release when they stayed empty (a refused run leaves nothing). `busy` ends the refusal's line."""

    def __init__(self, folder, comm, shared=False, busy="; wait for it to end or choose another output folder"):
        self.folder, self.fd, self.made = Path(folder), None, []
        refusal = self._acquire(fcntl.LOCK_SH if shared else fcntl.LOCK_EX, busy) if comm.rank == 0 else None
        refusal = comm.bcast(refusal, root=0)
        if refusal is not None:
            raise ConfigError("output.dir", refusal)

    def _acquire(self, mode, busy):
        """None once the lock is held, else why not."""
        problem = files.unwritable(self.folder)  # not a folder, read-only, ...: before anything is made
        if problem is not None:
            return problem
        try:
            self._lock_folder(mode)
            return None
        except OSError as err:
            self.release()
            if err.errno in (errno.EWOULDBLOCK, errno.EAGAIN):
                return f"{self.folder} is being written by another signorini run{busy}"
            return f"{err.filename or self.folder}: cannot write there: {err.strerror}"

    def _lock_folder(self, mode, tries=10):
        """Make the folder with its missing parents (recording only those this run made), open and lock it.
        Another run may make the same folders meanwhile, or remove an empty one it had made (its probe) before
        this run's next mkdir, open or lock: then start again from the top."""
        for attempt in range(tries):
            try:
                files.make_folders((*reversed(self.folder.parents), self.folder), self.made)
                self.fd = os.open(self.folder, os.O_RDONLY | os.O_DIRECTORY)
                fcntl.flock(self.fd, mode | fcntl.LOCK_NB)
                if os.path.samestat(os.fstat(self.fd), os.stat(self.folder)):
                    return
                raise FileNotFoundError(errno.ENOENT, "removed while being locked", str(self.folder))
            except FileNotFoundError:
                if self.fd is not None:
                    os.close(self.fd)
                    self.fd = None
                if attempt == tries - 1:
                    raise

    def release(self):
        if self.fd is not None:
            os.close(self.fd)  # closing the last descriptor drops the flock
            self.fd = None
        files.remove_empty(self.made)  # only empty folders: a run that wrote nothing leaves nothing
        self.made = []

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()
        return False


def try_lock(folder):
    """An exclusive flock on `folder` (made when missing) for this process: its descriptor (closing it
    drops the lock), or None when another run holds it."""
    Path(folder).mkdir(parents=True, exist_ok=True)
    fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as err:
        os.close(fd)
        if err.errno in (errno.EWOULDBLOCK, errno.EAGAIN):
            return None
        raise
    return fd


@contextmanager
def held(folder):
    """Within: an exclusive flock on `folder` (made when missing), waited for: what reads and rewrites
    files that other runs write too does so one run at a time."""
    Path(folder).mkdir(parents=True, exist_ok=True)
    fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


# --- a closed stdout -----------------------------------------------------------------------------

def raise_on_closed_pipes():
    """Writing to a closed pipe raises BrokenPipeError again (Python's default), instead of PETSc's
    SIGPIPE handler, which PetscInitialize installs, ending the run with exit 59 and its banner."""
    signal.signal(signal.SIGPIPE, signal.SIG_IGN)


@contextmanager
def stdout_may_close():
    """Within: printing to a closed stdout (`signorini run cfg | head -1`) stops the printing quietly,
    the rest of the run goes on; stdout then points at /dev/null so the exit's flush finds no pipe."""
    try:
        yield
        sys.stdout.flush()
    except BrokenPipeError:
        stdout_to_devnull()


def stdout_to_devnull():
    """Point stdout at /dev/null: what is still buffered for a closed pipe goes nowhere, quietly."""
    to_devnull(sys.stdout.fileno())


class Forgiving:
    """A text stream whose failed writes (its reader gone, a full disk, a closed descriptor, a hung-up
    terminal) are dropped: output that cannot be printed neither stops nor fails a study. After the first
    failure its descriptor points at /dev/null, so that later writes, PETSc's among them, and the flush at
    exit succeed."""

    def __init__(self, stream):
        self.stream = stream

    def write(self, text):
        try:
            return self.stream.write(text)
        except (OSError, ValueError):  # ValueError: the stream was closed
            self._drop()
            return len(text)

    def flush(self):
        try:
            self.stream.flush()
        except (OSError, ValueError):
            self._drop()

    def _drop(self):
        try:
            to_devnull(self.stream.fileno())
            self.stream.flush()  # what it still buffers goes to /dev/null now
        except (OSError, ValueError):
            pass

    def __getattr__(self, name):
        return getattr(self.stream, name)


def forgiving_streams():
    """stdout and stderr as Forgiving streams."""
    for name in ("stdout", "stderr"):
        if not isinstance(getattr(sys, name), Forgiving):
            setattr(sys, name, Forgiving(getattr(sys, name)))


def to_devnull(fd):
    """Point descriptor `fd` at /dev/null."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, fd)
    os.close(devnull)


# --- form compilation ----------------------------------------------------------------------------

@contextmanager
def compiling_whole():
    """Within: a signal waits while FFCx compiles a form (dolfinx.jit.ffcx_jit), and interrupts the run
    right after. FFCx claims a form's entry in its cache (~/.cache/fenics) with an empty .c file and cleans
    up only after an Exception: a run interrupted while compiling left the claim, and every later run of
    that form waited 10 s for it and failed. A compilation takes seconds. What the C compiler prints (gcc's
    unused-variable warnings on FFCx's code) is kept off stderr unless the compilation fails."""
    from dolfinx import jit
    original = jit.ffcx_jit

    @functools.wraps(original)
    def ffcx_jit(*args, **kwargs):
        _signals.holding += 1
        failure = ""
        try:
            with files.stderr_in_memory() as printed:  # the C compiler's warnings (unused variables) are noise
                try:
                    compiled = original(*args, **kwargs)
                except BaseException:
                    failure = printed()
                    raise
        except Exception:  # Ctrl-C reaches the compiler too: then the signal is the cause
            signum = _release()
            if signum is not None:
                raise Interrupted(signum) from None
            sys.stderr.write(failure)  # a failed compilation shows what the compiler said
            raise
        except BaseException:
            _release()
            raise
        signum = _release()
        if signum is not None:
            raise Interrupted(signum)
        return compiled

    jit.ffcx_jit = ffcx_jit
    try:
        yield
    finally:
        jit.ffcx_jit = original
