"""The console script's `--version`: the versions without starting MPI, PETSc or dolfinx."""
import subprocess
import sys

import pytest

from signorini_cli.system import version


@pytest.mark.fast
def test_version_loads_neither_mpi_nor_dolfinx():
    """`signorini --version` prints cli's line and imports none of the modules that start MPI or PETSc
    (they took 0.75 s of it: the command now costs about the interpreter's start)."""
    probe = ("import sys; sys.argv = ['signorini', '--version']; from signorini_cli.app import start; "
             "start.entry(); print(sorted(m for m in ('mpi4py', 'petsc4py', 'dolfinx', 'ufl') if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    import dolfinx
    line = f"signorini {version.version_line().split()[1]} (dolfinx {dolfinx.__version__})"
    assert done.stdout.splitlines() == [line, "[]"]
