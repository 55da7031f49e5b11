"""Atomic file writes: results and cached meshes are never seen half-written; the check that an
output folder can be made and written before a study starts; a C library's failed write as an OSError."""
import errno
import os
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path


def replace(path, write_to):
    """Call write_to(tmp) on a temporary file in path's folder, then rename it onto path.
    The temporary name keeps path's suffix (gmsh picks its format from it)."""
    replace_all([(path, write_to)])


def replace_all(writes):
    """replace() for several (path, write_to) at once: every temporary file is written before any is
    renamed, so a failure (a full disk) replaces none and the files keep describing the same levels."""
    staged = []
    try:
        for path, write_to in writes:
            staged.append((_temporary(Path(path)), Path(path)))
            write_to(staged[-1][0])
        for tmp, path in staged:
            os.replace(tmp, path)
    finally:
        for tmp, _ in staged:
            if tmp.exists():
                tmp.unlink()


def _temporary(path):
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=f".tmp{path.suffix}")
    os.close(fd)
    os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; these files are as readable as any new file
    return Path(tmp)


@contextmanager
def folder_for(folder):
    """Within: `folder` exists (made with its missing parents); when the block fails, the folders it made
    are removed again while empty: a failed write leaves no empty folder behind."""
    folder = Path(folder)
    made = [p for p in (*reversed(folder.parents), folder) if not p.exists()]
    folder.mkdir(parents=True, exist_ok=True)
    try:
        yield folder
    except BaseException:
        for path in reversed(made):
            try:
                path.rmdir()
            except OSError:
                break
        raise


def overwrite(path, text):
    """Write `text` over path in place: the last resort on a full disk, where a temporary copy finds no
    room but the file's own blocks, freed by the truncation, hold a line."""
    with open(path, "w") as f:
        f.write(text)


def unwritable(folder, tries=10):
    """None when `folder` (and its missing parents) can be made and a file written in it, else one line
    naming the path at fault. Leaves nothing behind: folders it made are removed again while empty. Another
    run may make, fill or remove the same folders meanwhile (a map's chunks starting together): a folder
    that vanished under the probe is probed again."""
    folder = Path(os.path.abspath(folder))
    for _ in range(tries):
        existing = next(p for p in (folder, *folder.parents) if os.path.lexists(p))
        if not existing.is_dir():
            if os.path.lexists(existing):
                return f"{existing} is not a folder"
            continue  # removed since it was seen
        problem = _probe(folder, _missing(folder, existing))
        if problem != "vanished":
            return problem
    return f"{folder}: cannot write there: other runs keep making and removing it"


def _probe(folder, missing):
    """Make the missing folders and a file in `folder`, then remove what was made: None, one line, or
    'vanished' when a folder was removed by another run meanwhile."""
    made = []
    try:
        make_folders(missing, made)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except FileNotFoundError:
        return "vanished"
    except OSError as err:
        return f"{err.filename or folder}: cannot write there: {err.strerror}"
    finally:
        remove_empty(made)
    return None


def make_folders(paths, made):
    """Make each of `paths` (outermost first) that is missing, adding those made to the list `made` (once
    each) as they are made; a path that is a file raises FileExistsError, a parent removed meanwhile
    FileNotFoundError."""
    for path in paths:
        try:
            path.mkdir()
            if path not in made:
                made.append(path)
        except FileExistsError:
            if not path.is_dir():
                raise


def remove_empty(made):
    """Remove the folders `made` (outermost first) from the innermost out, while they are empty: one that
    another run wrote into, or removed, stops it."""
    for path in reversed(made):
        try:
            path.rmdir()
        except OSError:
            break


def _missing(folder, existing):
    """The folders from below `existing` down to `folder`, outermost first."""
    below = [p for p in (folder, *folder.parents) if p != existing and existing in p.parents]
    return list(reversed(below))


def _umask():
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def library_writes(path):
    """Within: a C library writing `path` (HDF5 through dolfinx's XDMFFile) prints its diagnostics into memory
    instead of onto stderr, and its failure (a RuntimeError) is an OSError naming `path`: ENOSPC when the disk
    holds no free block, else EIO with the library's last line."""
    with stderr_in_memory() as printed:
        try:
            yield
        except RuntimeError as err:
            full = os.statvfs(Path(path).parent).f_bavail == 0
            code = errno.ENOSPC if full else errno.EIO
            lines = printed().strip().splitlines()
            last = lines[-1].strip() if lines else ""
            reason = os.strerror(code) if full else f"{os.strerror(code)}: {str(err).strip() or last}"
            raise OSError(code, reason, str(path)) from None


@contextmanager
def stderr_in_memory():
    """Within: descriptor 2 (sys.stderr too, and the programs started meanwhile) writes into an anonymous
    file in memory (not onto a full disk); yields a function giving what was written."""
    memory = os.memfd_create("stderr")
    sys.stderr.flush()
    saved = os.dup(2)
    os.dup2(memory, 2)

    def printed():
        sys.stderr.flush()
        os.lseek(memory, 0, os.SEEK_SET)
        return os.read(memory, 1 << 20).decode(errors="replace")
    try:
        yield printed
    finally:
        sys.stderr.flush()
        os.dup2(saved, 2)
        for fd in (saved, memory):
            os.close(fd)
