"""Atomic file writes: results and cached meshes are never seen half-written."""
import os
import tempfile
from pathlib import Path


def replace(path, write_to):
    """Call write_to(tmp) on a temporary file in path's folder, then rename it onto path.
    The temporary name keeps path's suffix (gmsh picks its format from it)."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=f".tmp{path.suffix}")
    os.close(fd)
    os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; these files are as readable as any new file
    try:
        write_to(Path(tmp))
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _umask():
    mask = os.umask(0)
    os.umask(mask)
    return mask
