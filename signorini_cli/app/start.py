"""The console script `signorini`: `--version` alone is answered from the installed metadata (no MPI, PETSc or
dolfinx starts for it: the command costs little more than the interpreter); every other command is cli.entry."""
import sys

from ..system.version import version_line


def entry():
    """`signorini --version`, or the command line (cli.entry)."""
    if sys.argv[1:] == ["--version"]:
        print(version_line())
        return 0
    from . import cli
    return cli.entry()
