"""Work in a forked child process: C code (gmsh) that does not see Python's signal handlers can be
killed from the parent, which does."""
import ctypes
import os
import pickle
import signal

SIGNALS = (signal.SIGINT, signal.SIGTERM)
PR_SET_PDEATHSIG = 1  # prctl(2): the signal a child gets when its parent dies


def in_child(work, *args):
    """work(*args) in a forked child process, its result (picklable) returned here, its exception
    raised here as a RuntimeError with its message. gmsh meshes in C, where a Python signal handler
    cannot run; here the parent waits, and SIGINT/SIGTERM kill the child and go on as Interrupted."""
    read_end, write_end = os.pipe()
    parent = os.getpid()
    pid = os.fork()
    if pid == 0:  # the child: no MPI, no atexit handlers, only work
        os.close(read_end)
        _child(work, args, write_end, parent)
    os.close(write_end)
    try:
        with os.fdopen(read_end, "rb") as pipe:
            answer = pipe.read()
        os.waitpid(pid, 0)
    except BaseException:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        raise
    kind, value = pickle.loads(answer) if answer else ("error", "the meshing process died")
    if kind == "error":
        raise RuntimeError(value)
    return value


def _child(work, args, write_end, parent):
    for sig in SIGNALS:
        signal.signal(sig, signal.SIG_DFL)
    # killed with its parent (kill -9 too): no orphan meshing on, holding the study folder's flock
    ctypes.CDLL(None).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    if os.getppid() != parent:  # the parent died before prctl
        os._exit(1)
    try:
        answer = ("ok", work(*args))
    except BaseException as err:  # whatever it is, the parent must hear of it
        answer = ("error", str(err) or type(err).__name__)
    with os.fdopen(write_end, "wb") as pipe:
        pipe.write(pickle.dumps(answer))
    os._exit(0)
