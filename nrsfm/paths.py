"""Where nrsfm reads its data and writes its outputs.

Outputs go under the folder the user started in (or ``$NRSFM_OUT``), never inside the
installed package; relative paths resolve against that folder, not against the process's
current directory (a Jupyter kernel runs in the notebook's folder but inherits ``PWD`` from
the shell that started Jupyter). A data folder may be the one that holds a data set's folder
(``mocap/``) or that folder itself.
"""

from __future__ import annotations

import os
from pathlib import Path

_PACKAGE_ROOT = Path(__file__).resolve().parent


def user_folder() -> Path:
    """The folder the user started in: ``$PWD`` when it is an absolute existing folder, else
    ``Path.cwd()``."""
    pwd = os.environ.get("PWD")
    if pwd and Path(pwd).is_absolute() and Path(pwd).is_dir():
        return Path(pwd)
    return Path.cwd()


def user_path(p) -> Path:
    """``p`` with ``~`` expanded and, if relative, resolved against :func:`user_folder` (an
    absolute path, not resolved through symlinks)."""
    path = Path(os.fspath(p)).expanduser()
    return path if path.is_absolute() else user_folder() / path


def output_dir(*parts) -> Path:
    """Folder for outputs, created with its parents: ``$NRSFM_OUT`` (through
    :func:`user_path`) if set, else ``user_folder() / "out"``, joined with ``parts``.

    Raises ValueError when the folder would lie inside the installed package, OSError when
    it cannot be created."""
    env = os.environ.get("NRSFM_OUT")
    folder = (user_path(env) if env else user_folder() / "out").joinpath(*parts)
    if folder.resolve().is_relative_to(_PACKAGE_ROOT):
        where = "lies inside the installed nrsfm package; set NRSFM_OUT or start elsewhere"
        raise ValueError(f"output folder {folder} {where}")
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def data_dir(data_dir=None) -> Path:
    """The data folder the user gave (through :func:`user_path`, not checked to exist):
    ``data_dir`` if given and not empty, else ``$NRSFM_DATA``; FileNotFoundError if none."""
    return _root(data_dir, "NRSFM_DATA", "mocap")


def _root(data, env, sub):
    names = (env,) if isinstance(env, str) else tuple(env)
    if data is None or os.fspath(data) == "":
        data = next((os.environ[n] for n in names if os.environ.get(n)), None)
    if data is None:
        give = f"pass the folder that holds {sub}/ (or {sub}/ itself), or set {' or '.join(names)}"
        raise FileNotFoundError(f"no data folder given: {give} to it")
    return user_path(data)


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
    """The first of ``root/sub/NAME``, ``root/NAME`` that exists, for each of ``names`` (a
    relative path or alternatives tried in order), where ``root`` is the folder given
    (``data``, else ``env``: see :func:`data_dir`) and ``sub`` the data set's folder
    (``"mocap"``).

    Raises FileNotFoundError (one line: the folders searched and the folder to give; ``what``
    names the file) when no folder is given or no such file exists."""
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
    raise FileNotFoundError(f"{what or 'file ' + names[0]} not found: looked in {looked}; {hint}")


def mocap_dir(data=None) -> Path:
    """The folder with the MoCap ``.mat`` files: ``root/mocap`` when it exists, else
    ``root`` (not checked to exist), where ``root`` is ``data`` or ``$NRSFM_DATA``."""
    root = _root(data, "NRSFM_DATA", "mocap")
    return root / "mocap" if (root / "mocap").is_dir() else root
