"""The package's and dolfinx's versions, read without importing dolfinx (`signorini --version` stays cheap)."""
from pathlib import Path


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
