"""The user's PETSc options tried before the first level: each SNES the study may build (newtonls or
newtontr, the VI's vinewtonrsls; LU and CG + AMG) solves a small linear system with them, so that an option
PETSc rejects (ILU with MUMPS, a preconditioner this PETSc was built without) is bad input, not a crash
inside a level. Also the net for a PETSc error that only a real solve meets: petsc_errors."""
import ctypes
import re
from contextlib import contextmanager

from mpi4py import MPI
from petsc4py import PETSc

from ..config import ConfigError
from ..config import petsc_options as petsc
from . import solver

N_PER_RANK = 8  # rows of the trial system on each rank: every rank owns some, as in a real level
PREFIX = "signorini_preflight_"
PETSC_LINE = re.compile(r"^\[\d+\]\s?(.*)$")  # PETSc's error lines: "[rank] text"


def check_options(solver_cfg, dim, comm=MPI.COMM_WORLD):
    """ConfigError on solver.petsc_options when PETSc rejects the options of a solver the study may build."""
    if not solver_cfg.petsc_options:
        return
    for linear in ("direct", "iterative"):
        options = {key: value for key, value in solver.petsc_options(solver_cfg, dim, linear=linear).items()
                   if not any(re.fullmatch(pattern, key) for pattern in petsc.VIEWER)}  # nothing printed
        for snes_type in (options["snes_type"], "vinewtonrsls"):
            _try(dict(options, snes_type=snes_type), comm)


def _try(options, comm):
    """Solve the trial system with `options`; PETSc's own error line as a ConfigError."""
    A, b = _trial_system(comm)
    snes, x = PETSc.SNES().create(comm), b.duplicate()
    opts = PETSc.Options()
    for key, value in options.items():
        opts[PREFIX + key] = value
    try:
        with petsc_errors():
            snes.setFunction(lambda snes, x, F: _affine(A, b, x, F), b.duplicate())
            snes.setJacobian(lambda snes, x, J, P: None, A)
            snes.setOptionsPrefix(PREFIX)
            snes.setFromOptions()
            x.set(0.0)
            snes.solve(None, x)
    finally:
        for key in options:
            opts.delValue(PREFIX + key)
        for obj in (snes, A, b, x):
            obj.destroy()


def _trial_system(comm):
    """A x = b with A the 1-D Laplacian (SPD, as the study's Jacobians), distributed over `comm`."""
    n = N_PER_RANK * comm.size
    A = PETSc.Mat().createAIJ(((N_PER_RANK, n), (N_PER_RANK, n)), nnz=(3, 1), comm=comm)
    start, end = A.getOwnershipRange()
    for i in range(start, end):
        A[i, i] = 2.0
        for j in (i - 1, i + 1):
            if 0 <= j < n:
                A[i, j] = -1.0
    A.assemble()
    b = A.createVecLeft()
    b.set(1.0)
    return A, b


def _affine(A, b, x, F):
    A.mult(x, F)
    F.axpy(-1.0, b)


@contextmanager
def petsc_errors(where=""):
    """Within: a PETSc error is a ConfigError on solver.petsc_options naming `where` and PETSc's reason
    (the last line of the report petsc4py keeps with the error, else PETSc's text for its code)."""
    try:
        yield
    except PETSc.Error as err:
        reason = _last_line(str(err)) or _message(err.ierr)
        raise ConfigError("solver.petsc_options", f"PETSc rejects these options{where}: {reason}") from None


def _last_line(text):
    lines = [m.group(1).strip() for m in map(PETSC_LINE.match, text.splitlines()) if m and m.group(1).strip()]
    return lines[-1] if lines else None


def _message(code):
    """PETSc's text for an error code (PetscErrorMessage; petsc4py 3.18 does not wrap it)."""
    text = ctypes.c_char_p()
    library = solver._petsc_library()
    library.PetscErrorMessage.argtypes = [ctypes.c_int, ctypes.POINTER(ctypes.c_char_p), ctypes.c_void_p]
    library.PetscErrorMessage(int(code), ctypes.byref(text), None)
    return f"PETSc error {int(code)}: {(text.value or b'').decode(errors='replace')}"
