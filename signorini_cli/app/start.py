"""The console script `signorini`: `--version` alone is answered from the installed metadata (no MPI, PETSc or
dolfinx starts for it: the command costs little more than the interpreter); every other command is cli.entry."""
import sys
from pathlib import Path


def entry():
    """`signorini --version`, or the command line (cli.entry)."""
    if sys.argv[1:] == ["--version"]:
        print(version_line())
        return 0
    from . import cli
    return cli.entry()


def version_line():
    """'signorini <version> (dolfinx <version>)'."""
    from .. import __version__
    return f"signorini {__version__} (dolfinx {dolfinx_version()})"


def dolfinx_version():
    """dolfinx's version from its distribution's folder beside it (fenics_dolfinx-<version>.egg-info or
    .dist-info), found without importing dolfinx or scanning every installed distribution."""
    from importlib.util import find_spec
    spec = find_spec("dolfinx")
    site = Path(spec.origin).parent.parent
    for info in sorted(site.glob("fenics_dolfinx-*.*-info")):
        return info.name.removeprefix("fenics_dolfinx-").rsplit(".", 1)[0]
    import dolfinx  # no metadata folder (a build tree): ask the module
    return dolfinx.__version__
