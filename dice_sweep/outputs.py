"""Checks of the files and folders a command will write, made before any work (issue 16).

Every command that writes calls :func:`check_outputs` first, so that a path that cannot be
written is one line naming the option, the path and what is allowed, before a sweep or a fit
runs rather than after it. Imports nothing heavy: the image formats come from
:func:`dice_sweep.plotting.image_formats`, asked for only by commands that draw.

Then every file is written the same way (issue 32): under a temporary name beside it, renamed
once complete (:func:`written`), a command's files together once it succeeds (:func:`together`),
a full disk one line naming the file; HDF5 writes check the space first (:func:`check_space`).
"""

import contextlib
import contextvars
import json
import os
import shutil
import tempfile
from pathlib import Path

from dice_sweep.errors import DiceSweepError

PARTIAL = ".partial"  # what make and the SLURM scripts write to before renaming (docs/scaling.md)
HDF5 = (".h5", ".hdf5")
SWEEP_FILE = HDF5 + tuple(suffix + PARTIAL for suffix in HDF5)  # sweep -o, merge -o
JSON = (".json",)
MARKDOWN = (".md",)
NPZ = (".npz",)  # numpy.savez appends .npz to any other name
CSV = (".csv", ".csv.gz")
GIF = (".gif",)
FOLDER = None  # the suffixes of an output that is a folder (of pictures), created if missing


def _one_of(suffixes) -> str:
    return suffixes[0] if len(suffixes) == 1 else f"{', '.join(suffixes[:-1])} or {suffixes[-1]}"


def _allowed(suffixes) -> str:
    where = "in an existing folder you may write to"
    if suffixes is FOLDER:
        return f"a folder (created if missing) {where}"
    return f"a file name ending in {_one_of(suffixes)} {where}"


def _writable_folder(folder: Path) -> bool:
    """True if a file can be created in ``folder`` (tried, then removed: root passes
    os.access everywhere, yet cannot write to /sys or a read-only mount)."""
    if not os.access(folder, os.W_OK | os.X_OK):
        return False
    try:
        handle, probe = tempfile.mkstemp(dir=folder, prefix=".dice-sweep-write-test-")
    except OSError:
        return False
    os.close(handle)
    os.unlink(probe)
    return True


def _problem(path: Path, suffixes) -> str | None:
    """What makes ``path`` impossible to write as an output of this kind (None: nothing)."""
    is_folder = suffixes is FOLDER
    name = path.name.lower()
    if not is_folder and not any(name.endswith(suffix) and len(name) > len(suffix) for suffix in suffixes):
        return "wrong file extension" if name not in suffixes else "nothing before the extension"
    if path.is_dir() and not is_folder:
        return "is a folder"
    if path.exists() and is_folder and not path.is_dir():
        return "is a file"
    parent = path.parent
    if not parent.exists():
        return f"folder {parent} does not exist"
    if not parent.is_dir():
        return f"{parent} is a file, not a folder"
    if path.exists() and not os.access(path, os.W_OK | (os.X_OK if is_folder else 0)):
        return "cannot be written (permission denied)"
    if not path.exists() and not _writable_folder(parent):
        return f"folder {parent} cannot be written to"
    return None


def check_outputs(*outputs) -> None:
    """Refuse, with one line, outputs that cannot be written, before any work.

    Parameters
    ----------
    *outputs : tuple of (str, path or None, tuple of str or None)
        (option, path, allowed suffixes) of each output; a None path (an option not given)
        is skipped; suffixes :data:`FOLDER` for a folder that is created if missing.

    Raises
    ------
    DiceSweepError
        ``OPTION: PATH: what is wrong (allowed: ...)`` for the first output whose name does
        not end in an allowed suffix (case ignored), that is a folder (or, for a folder, a
        file), whose folder does not exist or cannot be written to; or when two outputs are
        the same path.
    """
    given = [(option, Path(path), suffixes) for option, path, suffixes in outputs if path]
    for option, path, suffixes in given:
        problem = _problem(path, suffixes)
        if problem is not None:
            raise DiceSweepError(f"{option}: {path}: {problem} (allowed: {_allowed(suffixes)})")
    seen = {}
    for option, path, _ in given:
        where = os.path.realpath(path)
        if where in seen:
            raise DiceSweepError(f"{option}: {path}: also given to {seen[where]} (allowed: a different path for each output)")
        seen[where] = option


def _ending(path: Path) -> str:
    """The extension a writer goes by (``.png``; ``.csv.gz`` whole)."""
    suffixes = path.suffixes
    return "".join(suffixes[-2:]) if len(suffixes) > 1 and suffixes[-1].lower() == ".gz" else path.suffix


def write_error(path, error: OSError) -> DiceSweepError:
    """One line naming the output and why it could not be written (a full disk, a folder gone)."""
    cause = error.strerror or " ".join(str(error).split())
    code = f" (errno {error.errno})" if error.errno else ""
    return DiceSweepError(f"{path}: cannot be written: {cause}{code}; nothing was written to it")


_UMASK = os.umask(0o022)
os.umask(_UMASK)  # read once: mkstemp makes files 0600, an output gets the usual 0666 & ~umask


_PENDING = contextvars.ContextVar("pending_outputs", default=None)  # the renames :func:`together` holds back


@contextlib.contextmanager
def written(path, *, replace=True, defer=True):
    """Yield a temporary path in the folder of ``path``, ending as ``path`` does (matplotlib,
    Pillow and numpy choose the format by the name); when the block ends, rename it to
    ``path``: the whole file or nothing. On any error the temporary is removed; an OSError
    (a full disk, say) becomes one :func:`write_error` line naming ``path``. With
    ``replace=False`` an existing ``path`` is never replaced (the rename is a hard link).
    Inside :func:`together` the rename waits for the end of that block (unless ``defer`` is
    False: a file read back at once). The one way every command writes a file (issue 32)."""
    path = Path(path)
    try:
        handle, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=PARTIAL + _ending(path))
    except OSError as error:
        raise write_error(path, error) from None
    os.close(handle)
    temporary = Path(name)
    pending = _PENDING.get() if defer else None
    try:
        yield temporary
        if pending is not None:
            pending.append((temporary, path, replace))
            return
        _rename(temporary, path, replace)
    except OSError as error:
        raise write_error(path, error) from None
    finally:
        if pending is None or (temporary, path, replace) not in pending:
            temporary.unlink(missing_ok=True)


def _rename(temporary: Path, path: Path, replace: bool) -> None:
    os.chmod(temporary, 0o666 & ~_UMASK)
    if replace:
        os.replace(temporary, path)
    else:
        os.link(temporary, path)
        temporary.unlink()


@contextlib.contextmanager
def together():
    """Hold back the renames of the files :func:`written` inside the block until it ends
    without error, so that a command's outputs appear together or not at all (a full disk at
    its last picture leaves no report that looks complete without it)."""
    pending = []
    token = _PENDING.set(pending)
    try:
        yield
        for temporary, path, replace in (entry for entry in pending if entry[0] is not None):
            try:
                _rename(temporary, path, replace)
            except OSError as error:
                raise write_error(path, error) from None
        pending.clear()
    finally:
        _PENDING.reset(token)
        for temporary, path, _ in reversed(pending):
            if temporary is not None:
                temporary.unlink(missing_ok=True)
            elif path.is_dir() and not any(path.iterdir()):
                path.rmdir()  # a picture folder the failed command made, left empty


def make_folder(path) -> Path:
    """Create the folder ``path`` (and missing parents) for a command's pictures; inside
    :func:`together`, one it created is removed again, if empty, when the command fails."""
    path = Path(path)
    missing = [folder for folder in (path, *path.parents) if not folder.exists()]
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise write_error(path, error) from None
    pending = _PENDING.get()
    if pending is not None:
        pending.extend((None, folder, False) for folder in reversed(missing))
    return path


def replace_atomically(path, write):
    """Call ``write(binary file)`` on a temporary file, then rename it to ``path``
    (:func:`written`): the whole file or nothing (a killed run leaves no half-written output)."""
    with written(path) as temporary, open(temporary, "wb") as file:
        write(file)


def write_json(path, data, *, indent=2) -> Path:
    """Write ``data`` as indented JSON (and a newline), the whole file or nothing
    (:func:`replace_atomically`); return the path. The one JSON writer of the commands."""
    text = json.dumps(data, indent=indent) + "\n"
    replace_atomically(path, lambda file: file.write(text.encode("utf-8")))
    return Path(path)


HDF5_SPARE = 1 << 20  # bytes left free beside a write to a sweep file: HDF5's own metadata


def free_bytes(folder) -> int:
    """Bytes a process may still write in ``folder``'s file system."""
    return shutil.disk_usage(folder).free


def check_space(path, needed: int, advice: str = "") -> None:
    """Refuse, before writing, ``needed`` bytes (plus :data:`HDF5_SPARE`) to ``path`` on a
    file system without them: HDF5 that meets a full disk in the middle of a write leaves
    its file open in a state it cannot close, and the process dies at exit (a segfault)."""
    free = free_bytes(Path(path).parent)
    if free < needed + HDF5_SPARE:
        raise DiceSweepError(f"{path}: no space left on the device: {free} bytes free, {needed + HDF5_SPARE} needed "
                             f"(the data and {HDF5_SPARE} bytes spare for HDF5){advice}")
