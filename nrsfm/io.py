"""Atomic output files (the one home of atomic writes): write beside the target, then
rename over it; and :func:`load_npz`, the one reader of input ``.npz`` files.

A write that fails half-way (disk full, file-size limit, an exception while the content is
produced) leaves an existing output untouched and no partial file behind. A file that
cannot be read as an ``.npz`` of arrays raises a ``ValueError`` that names the file, what it
looks like and what was expected; nothing is ever unpickled, and no message suggests it.
"""

from __future__ import annotations

import io

import os
import tempfile
import zipfile
import zlib
from contextlib import contextmanager
from pathlib import Path

import numpy as np

__all__ = ["atomic_output", "check_output_path", "load_npz", "save_npz", "write_text"]

#: What :func:`load_npz` reads, for its messages.
NPZ_EXPECTED = "an .npz archive of numeric arrays, as written by numpy.savez"


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


def _looks_like(head):
    """What the first bytes of a file that is not a zip archive look like."""
    if head.startswith(b"\x93NUMPY"):
        return "a .npy file (one array)"
    if head[:1] == b"\x80" or head.startswith((b"(dp", b"(lp", b"}q")):
        return "a Python pickle (never loaded)"
    text = None
    for cut in range(4):         # the 64 bytes may end inside a multi-byte character
        try:
            text = head[:len(head) - cut].decode("utf-8")
            break
        except UnicodeDecodeError:
            continue
    if text and all(c.isprintable() or c in "\t\r\n" for c in text):
        return f"a text file (it starts with {' '.join(text.split())[:40]!r})"
    return "a binary file of an unknown kind"


def _reason(exc):
    """A one-line reason from a reader's exception, without numpy's advice to unpickle."""
    text = " ".join(str(exc).split())
    if not text or "pickle" in text.lower():
        return type(exc).__name__
    return text[:200]


def _open_npz(path, what, expected):
    """``numpy.load`` of a checked file, with plain messages for every unreadable one."""
    path = Path(path).expanduser()
    if path.is_dir():
        raise ValueError(f"{what} {path} is a folder; expected {expected}")
    if not path.is_file():
        raise FileNotFoundError(f"{what} file {path} not found")
    with open(path, "rb") as f:
        head = f.read(64)
    if not head:
        raise ValueError(f"{what} {path} is empty; expected {expected}")
    if not head.startswith((b"PK\x03\x04", b"PK\x05\x06")):
        raise ValueError(f"cannot read {what} {path}: not an .npz archive, it is "
                         f"{_looks_like(head)}; expected {expected}")
    try:                  # from memory: a corrupt archive leaves no file handle open
        return path, np.load(io.BytesIO(path.read_bytes()), allow_pickle=False)
    except (ValueError, OSError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        raise ValueError(f"cannot read {what} {path}: corrupt .npz archive "
                         f"({_reason(exc)}); expected {expected}") from exc


def load_npz(path, what="input", expected=NPZ_EXPECTED):
    """The arrays of an ``.npz`` file, read without unpickling anything.

    Parameters
    ----------
    path : str or os.PathLike
    what : str
        What the file is, for messages (``"input"``, ``"--ground-truth"``).
    expected : str
        What the file should be, for messages.

    Returns
    -------
    arrays : dict of str to ndarray

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        A folder, an empty file, a file that is not a zip archive (a text file, a ``.npy``,
        a pickle, ...), a corrupt archive, an object array or a member that is not an
        array: one line naming the file, what it holds and ``expected``.
    """
    path, loaded = _open_npz(path, what, expected)
    data = {}
    with loaded as z:
        for key in z.files:
            try:
                value = z[key]
            except ValueError as exc:
                if "pickle" in str(exc) or "Object arrays" in str(exc):
                    raise ValueError(f"{what} {path}: array {key!r} is an object array "
                                     "(arrays of Python objects are not read); save "
                                     "numeric arrays only") from exc
                raise ValueError(f"cannot read array {key!r} of {what} {path}: "
                                 f"{_reason(exc)}") from exc
            except (EOFError, OSError, zipfile.BadZipFile, zlib.error, KeyError) as exc:
                raise ValueError(f"cannot read array {key!r} of {what} {path}: corrupt "
                                 f".npz archive ({_reason(exc)})") from exc
            if not isinstance(value, np.ndarray):
                raise ValueError(f"{what} {path}: member {key!r} is not a NumPy array; "
                                 f"expected {expected}")
            data[key] = value
    return data
