"""Where nrsfm reads its data and writes its outputs.

Outputs go under the folder the user started in (or ``$NRSFM_OUT``), never inside the
installed package; relative paths resolve against that folder, not against the process's
current directory (a Jupyter kernel runs in the notebook's folder but inherits ``PWD`` from
the shell that started Jupyter).
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["user_folder", "user_path", "output_dir", "data_dir"]

_PACKAGE_ROOT = Path(__file__).resolve().parent


def user_folder() -> Path:
    """The folder the user started in.

    Returns
    -------
    folder : Path
        ``$PWD`` when it is set, absolute and an existing directory; else ``Path.cwd()``.
    """
    pwd = os.environ.get("PWD")
    if pwd:
        p = Path(pwd)
        if p.is_absolute() and p.is_dir():
            return p
    return Path.cwd()


def user_path(p) -> Path:
    """``p`` with ``~`` expanded and, if relative, resolved against :func:`user_folder`.

    Parameters
    ----------
    p : str or os.PathLike

    Returns
    -------
    path : Path
        An absolute path (not resolved through symlinks).
    """
    path = Path(os.fspath(p)).expanduser()
    if not path.is_absolute():
        path = user_folder() / path
    return path


def _inside_package(path: Path) -> bool:
    try:
        path.resolve().relative_to(_PACKAGE_ROOT)
    except ValueError:
        return False
    return True


def output_dir(*parts) -> Path:
    """Folder for outputs, created with its parents.

    Parameters
    ----------
    *parts : str
        Sub-folders joined onto the base folder.

    Returns
    -------
    folder : Path
        ``$NRSFM_OUT`` (through :func:`user_path`) if set, else ``user_folder() / "out"``,
        joined with ``parts``.

    Raises
    ------
    ValueError
        The folder would lie inside the installed package.
    OSError
        The folder cannot be created.
    """
    env = os.environ.get("NRSFM_OUT")
    base = user_path(env) if env else user_folder() / "out"
    folder = base.joinpath(*parts)
    if _inside_package(folder):
        raise ValueError(f"output folder {folder} lies inside the installed nrsfm package; "
                         "set NRSFM_OUT or start from another folder")
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def data_dir(data_dir=None) -> Path:
    """Benchmark data folder (the one that holds ``mocap/``).

    Parameters
    ----------
    data_dir : str or os.PathLike, optional
        Explicit folder; defaults to ``$NRSFM_DATA``.

    Returns
    -------
    folder : Path
        The folder through :func:`user_path` (it is not checked to exist).

    Raises
    ------
    FileNotFoundError
        Neither ``data_dir`` nor ``$NRSFM_DATA`` is given.
    """
    if data_dir is None or os.fspath(data_dir) == "":
        data_dir = os.environ.get("NRSFM_DATA") or None
    if data_dir is None:
        raise FileNotFoundError("no data folder given: set NRSFM_DATA to the folder that "
                                "holds mocap/ (or pass data_dir=...)")
    return user_path(data_dir)
