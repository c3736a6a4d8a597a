"""Atomic output files (the one home of atomic writes): write beside the target, then
rename over it.

A write that fails half-way (disk full, file-size limit, an exception while the content is
produced) leaves an existing output untouched and no partial file behind.
"""

from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np

__all__ = ["atomic_output", "check_output_path", "save_npz", "write_text"]


def _umask():
    mask = os.umask(0)
    os.umask(mask)
    return mask


def check_output_path(path, what="output"):
    """Check, before any computation, that ``path`` can be written as a file.

    Parameters
    ----------
    path : str or os.PathLike
        The exact file to write.
    what : str
        Name used in error messages (e.g. ``"output"``, ``"--rrd"``).

    Returns
    -------
    path : Path

    Raises
    ------
    ValueError
        ``path`` is empty or an existing folder or not a regular file.
    FileNotFoundError
        Its folder does not exist.
    PermissionError
        Its folder (or the existing file) is not writable.
    """
    if os.fspath(path) == "":
        raise ValueError(f"{what} path is empty")
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{what} {path} is an existing folder; give a file name")
    if path.exists() and not path.is_file():
        raise ValueError(f"{what} {path} exists and is not a regular file")
    folder = path.parent
    if not folder.is_dir():
        raise FileNotFoundError(f"{what} folder {folder} does not exist")
    if path.exists() and not os.access(path, os.W_OK):
        raise PermissionError(f"{what} {path} exists and is read-only")
    try:  # a real probe: os.access says yes to root on read-only folders and mounts
        fd, probe = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".probe", dir=folder)
    except OSError as exc:
        raise PermissionError(f"{what} folder {folder} is not writable "
                              f"({exc.strerror or exc})") from exc
    os.close(fd)
    os.unlink(probe)
    return path


@contextmanager
def atomic_output(path):
    """Yield a temporary path beside ``path``; on success rename it to ``path``.

    Parameters
    ----------
    path : str or os.PathLike
        The final file. Its folder must exist.

    Yields
    ------
    tmp : Path
        A new empty file in the same folder with the same suffix; write it completely.

    Notes
    -----
    On an exception inside the block the temporary file is removed and ``path`` is left as
    it was. On success the file gets the permissions of the file it replaces (or the
    default ones under the umask) and is renamed over ``path`` with :func:`os.replace`.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=f".tmp{path.suffix}",
                               dir=path.parent)
    os.close(fd)
    tmp = Path(tmp)
    try:
        yield tmp
        mode = path.stat().st_mode & 0o7777 if path.exists() else 0o666 & ~_umask()
        os.chmod(tmp, mode)
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            tmp.unlink()
        except OSError:
            pass
        raise


def save_npz(path, compressed=True, **arrays):
    """Write ``arrays`` to exactly ``path`` (no ``.npz`` appended), atomically.

    Parameters
    ----------
    path : str or os.PathLike
    compressed : bool
        :func:`numpy.savez_compressed` (default) or :func:`numpy.savez`.
    **arrays : array_like

    Returns
    -------
    path : Path
    """
    path = Path(path)
    save = np.savez_compressed if compressed else np.savez
    with atomic_output(path) as tmp:
        with open(tmp, "wb") as f:  # a file object: numpy appends no suffix
            save(f, **arrays)
            f.flush()
    return path


def write_text(path, text):
    """Write the string ``text`` to exactly ``path``, atomically (:func:`atomic_output`).

    Parameters
    ----------
    path : str or os.PathLike
        The final file. Its folder must exist.
    text : str

    Returns
    -------
    path : Path
    """
    path = Path(path)
    with atomic_output(path) as tmp:
        tmp.write_text(text)
    return path
