"""Where nrsfm reads its data and writes its outputs.

Outputs go under the folder the user started in (or ``$NRSFM_OUT``), never inside the
installed package; relative paths resolve against that folder, not against the process's
current directory (a Jupyter kernel runs in the notebook's folder but inherits ``PWD`` from
the shell that started Jupyter).
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["user_folder", "user_path", "output_dir", "data_dir", "data_subdir",
           "find_data_file", "mocap_dir"]

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


def data_dir(data_dir=None, env="NRSFM_DATA") -> Path:
    """The data folder the user gave: ``data_dir``, else ``$NRSFM_DATA``.

    The folder may be the one that holds ``mocap/`` or ``mocap/`` itself: the loaders take
    either (:func:`data_subdir`).

    Parameters
    ----------
    data_dir : str or os.PathLike, optional
        Explicit folder (``--data``, ``data_dir=``); an empty string counts as not given.
    env : str or tuple of str
        Environment variable(s) read, in order, when ``data_dir`` is not given.

    Returns
    -------
    folder : Path
        The folder through :func:`user_path` (it is not checked to exist).

    Raises
    ------
    FileNotFoundError
        Neither ``data_dir`` nor any of the variables is given.
    """
    return _root(data_dir, env, "mocap")


def _root(data, env, sub):
    names = (env,) if isinstance(env, str) else tuple(env)
    if data is None or os.fspath(data) == "":
        data = next((os.environ[n] for n in names if os.environ.get(n)), None)
    if data is None:
        raise FileNotFoundError(f"no data folder given: pass the folder that holds {sub}/ "
                                f"(or {sub}/ itself), or set {' or '.join(names)} to it")
    return user_path(data)


def data_subdir(sub, data=None, env="NRSFM_DATA") -> Path:
    """The folder with the files of one data set, from the folder the user gave.

    Parameters
    ----------
    sub : str
        The data set's folder name, e.g. ``"mocap"``.
    data, env
        As for :func:`data_dir`: the folder that holds ``sub/``, or ``sub/`` itself.

    Returns
    -------
    folder : Path
        ``root / sub`` when that folder exists, else ``root`` (not checked to exist).

    Raises
    ------
    FileNotFoundError
        No folder given (see :func:`data_dir`).
    """
    root = _root(data, env, sub)
    return root / sub if (root / sub).is_dir() else root


def _state(folder):
    if folder.is_dir():
        return str(folder)
    return f"{folder} ({'not a folder' if folder.exists() else 'no such folder'})"


def _nearby(root, names, limit=200):
    """A sub-folder of ``root`` (one level down, at most ``limit`` looked at) that holds one
    of the relative paths ``names``, or None."""
    try:
        children = sorted(c for c in root.iterdir() if c.is_dir())[:limit]
    except OSError:
        return None
    return next((c for c in children for n in names if (c / n).is_file()), None)


def find_data_file(names, sub, data=None, env="NRSFM_DATA", what=None) -> Path:
    """Path of a data file under the folder the user gave (``root/sub/`` or ``root/``).

    Parameters
    ----------
    names : str or sequence of str
        The file's path relative to the data set's folder, or alternatives tried in order
        (e.g. ``("hulk/data_hulk.mat", "data_hulk.mat")``).
    sub : str
        The data set's folder name (``"mocap"``).
    data, env
        As for :func:`data_dir`: the folder that holds ``sub/``, or ``sub/`` itself.
    what : str, optional
        What the file is, for the error message (default: ``file NAME``).

    Returns
    -------
    path : Path
        The first of ``root/sub/NAME``, ``root/NAME`` (for each name in turn) that exists.

    Raises
    ------
    FileNotFoundError
        No folder given, or no such file. The one-line message names the folders searched
        and the folder to give (when a sub-folder of ``root`` holds the file: that one).
    """
    names = (names,) if isinstance(names, str) else tuple(names)
    root = _root(data, env, sub)
    searched = [root / sub, root] if root.name != sub else [root]
    for name in names:
        for folder in searched:
            if (folder / name).is_file():
                return folder / name
    var = env if isinstance(env, str) else " or ".join(env)
    hint = f"pass the folder that holds {sub}/ (or {sub}/ itself), or set {var} to it"
    found = _nearby(root, [f"{sub}/{n}" for n in names] + list(names))
    if found is not None:
        hint = f"{found} holds it: use that folder"
    looked = " and ".join(_state(f) for f in searched)
    raise FileNotFoundError(f"{what or 'file ' + names[0]} not found: looked in {looked}; "
                            f"{hint}")


def mocap_dir(data=None) -> Path:
    """The folder with the MoCap ``.mat`` files: :func:`data_subdir` of ``"mocap"``.

    Parameters
    ----------
    data : str or os.PathLike, optional
        The folder that holds ``mocap/``, or ``mocap/`` itself; default ``$NRSFM_DATA``
        (either form too).

    Returns
    -------
    folder : Path
    """
    return data_subdir("mocap", data)
