"""Output files written atomically (beside the target, then renamed over it), and
:func:`load_npz`, the one reader of input ``.npz`` files.

A write that fails half-way leaves an existing output untouched and no partial file behind. A
file that cannot be read as an ``.npz`` of arrays raises a one-line ``ValueError`` naming the
file, what it looks like and what was expected; nothing is ever unpickled.
"""

from __future__ import annotations

import io
import os
import tempfile
import zipfile
import zlib
from contextlib import contextmanager, suppress
from pathlib import Path

import numpy as np

_ZIP_ERRORS = (EOFError, OSError, zipfile.BadZipFile, zlib.error)


def check_output_path(path, what="output"):
    """``path`` as a Path, checked before any computation to be writable as a file (``what``
    names it in messages): ValueError if it is empty, a folder or not a regular file,
    FileNotFoundError if its folder does not exist, PermissionError if it is not writable."""
    if os.fspath(path) == "":
        raise ValueError(f"{what} path is empty")
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{what} {path} is an existing folder; give a file name")
    if path.exists() and not path.is_file():
        raise ValueError(f"{what} {path} exists and is not a regular file")
    if not path.parent.is_dir():
        raise FileNotFoundError(f"{what} folder {path.parent} does not exist")
    if path.exists() and not os.access(path, os.W_OK):
        raise PermissionError(f"{what} {path} exists and is read-only")
    try:  # a real probe: os.access says yes to root on read-only folders and mounts
        fd, probe = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".probe", dir=path.parent)
    except OSError as exc:
        reason = exc.strerror or exc
        raise PermissionError(f"{what} folder {path.parent} is not writable ({reason})") from exc
    os.close(fd)
    os.unlink(probe)
    return path


def _remove_stale(path):
    """Remove the temporary files that an earlier write of ``path`` left behind when its
    process was killed (their process id, in the name, no longer runs)."""
    for tmp in path.parent.glob(f".{path.name}.*.tmp{path.suffix}"):
        pid = tmp.name[len(path.name) + 2 :].split(".")[0]
        if pid.isdigit() and int(pid) != os.getpid():
            try:
                os.kill(int(pid), 0)  # raises where no such process runs
            except ProcessLookupError:
                with suppress(OSError):
                    tmp.unlink()
            except OSError:  # another user's process, running
                pass


@contextmanager
def atomic_output(path):
    """Yield a new empty temporary file beside ``path`` (whose folder must exist), with the
    same suffix; on success it gets the permissions of the file it replaces (or the default
    ones under the umask) and is renamed over ``path``. On an exception it is removed and
    ``path`` is left as it was."""
    path = Path(path)
    _remove_stale(path)
    fd, tmp = tempfile.mkstemp(
        prefix=f".{path.name}.{os.getpid()}.", suffix=f".tmp{path.suffix}", dir=path.parent
    )
    os.close(fd)
    tmp = Path(tmp)
    try:
        yield tmp
        if path.exists():
            mode = path.stat().st_mode & 0o7777
        else:
            umask = os.umask(0)
            os.umask(umask)
            mode = 0o666 & ~umask
        os.chmod(tmp, mode)
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with suppress(OSError):
            tmp.unlink()
        raise


def save_npz(path, compressed=True, **arrays):
    """Write ``arrays`` to exactly ``path`` (no ``.npz`` appended), atomically, with
    :func:`numpy.savez_compressed` (or :func:`numpy.savez`); returns ``path`` as a Path."""
    path = Path(path)
    with atomic_output(path) as tmp, open(tmp, "wb") as f:  # a file object: no suffix added
        (np.savez_compressed if compressed else np.savez)(f, **arrays)
    return path


def write_text(path, text):
    """Write the string ``text`` to exactly ``path``, atomically; returns it as a Path."""
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
    for cut in range(4):  # the 64 bytes may end inside a multi-byte character
        try:
            text = head[: len(head) - cut].decode("utf-8")
        except UnicodeDecodeError:
            continue
        if all(c.isprintable() or c in "\t\r\n" for c in text):
            return f"a text file (it starts with {' '.join(text.split())[:40]!r})"
        break
    return "a binary file of an unknown kind"


def _reason(exc):
    """A one-line reason from a reader's exception, without numpy's advice to unpickle."""
    text = " ".join(str(exc).split())
    return type(exc).__name__ if not text or "pickle" in text.lower() else text[:200]


def load_npz(path, what="input", expected="an .npz archive of numeric arrays (numpy.savez)"):
    """The arrays (a dict) of an ``.npz`` file, read without unpickling anything; ``what`` the
    file is and what it should be (``expected``) for messages. FileNotFoundError for no such
    file; ValueError for a folder, an empty file, a file that is not a zip archive (text,
    ``.npy``, pickle, ...), a corrupt archive, an object array or a member not an array."""
    path = Path(path).expanduser()
    name = f"{what} {path}"
    if path.is_dir():
        raise ValueError(f"{name} is a folder; expected {expected}")
    if not path.is_file():
        raise FileNotFoundError(f"{what} file {path} not found")
    raw = path.read_bytes()
    if not raw:
        raise ValueError(f"{name} is empty; expected {expected}")
    if not raw.startswith((b"PK\x03\x04", b"PK\x05\x06")):
        it = _looks_like(raw[:64])
        raise ValueError(
            f"cannot read {name}: not an .npz archive, it is {it}; expected {expected}"
        )
    try:
        archive = np.load(io.BytesIO(raw), allow_pickle=False)
    except (ValueError, *_ZIP_ERRORS) as exc:
        raise ValueError(
            f"cannot read {name}: corrupt .npz archive ({_reason(exc)}); expected {expected}"
        ) from exc
    data = {}
    with archive as z:
        for key in z.files:
            member = f"array {key!r} of {name}"
            try:
                value = z[key]
            except ValueError as exc:
                if "pickle" in str(exc) or "Object arrays" in str(exc):
                    why = "(arrays of Python objects are not read); save numeric arrays only"
                    raise ValueError(f"{name}: array {key!r} is an object array {why}") from exc
                raise ValueError(f"cannot read {member}: {_reason(exc)}") from exc
            except (*_ZIP_ERRORS, KeyError) as exc:
                raise ValueError(
                    f"cannot read {member}: corrupt .npz archive ({_reason(exc)})"
                ) from exc
            if not isinstance(value, np.ndarray):
                raise ValueError(
                    f"{name}: member {key!r} is not a NumPy array; expected {expected}"
                )
            data[key] = value
    return data
