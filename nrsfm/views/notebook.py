"""Where notebooks and scripts write files, how a path is shown, and an embedded Rerun viewer
in a live notebook."""

from __future__ import annotations

import os
import sys
from pathlib import Path


def output_path(name, subdir="notebooks"):
    """``output_dir(subdir) / name``: under ``$NRSFM_OUT`` if set, else ``out/<subdir>/`` in
    the folder the user started in (never inside the installed package); folder created."""
    from ..paths import output_dir

    return output_dir(subdir) / name


def shown_path(path):
    """``path`` relative to the folder the user started in when it lies below it (for
    messages and rendered notebooks), else as given."""
    from ..paths import user_folder

    try:
        return Path(path).resolve().relative_to(user_folder().resolve())
    except ValueError:
        return Path(path)


def _interactive():
    """Whether a notebook front end will show an embedded viewer: ``NRSFM_VIEWER=1`` or
    ``0`` decides; ``NRSFM_NO_VIEWER``, ``CI`` or a pytest run turn it off; otherwise an
    IPython kernel started by a Jupyter server (``JPY_SESSION_NAME``) or VS Code (a kernel
    run by ``jupyter nbconvert --execute`` has no front end)."""
    flag = os.environ.get("NRSFM_VIEWER")
    if flag in ("0", "1"):
        return flag == "1"
    if any(os.environ.get(v) for v in ("CI", "PYTEST_CURRENT_TEST", "NRSFM_NO_VIEWER")):
        return False
    ipy = sys.modules.get("IPython")
    shell = ipy.get_ipython() if ipy is not None else None
    if shell is None or getattr(shell, "kernel", None) is None:
        return False
    return bool(os.environ.get("JPY_SESSION_NAME") or os.environ.get("VSCODE_PID"))


def show_recording(path, width=1000, height=720, blueprint=None):
    """Embed a viewer of the ``.rrd`` at ``path`` in a live notebook, else print how to open
    it (returns nothing: a notebook cell that ends with it shows no value).

    The file is sent as it is (its blueprint, under its own application id; ``blueprint``
    replaces it); the viewer's code is inlined from the installed ``rerun-notebook`` (works
    offline; ``RERUN_NOTEBOOK_ASSET`` overrides). Needs the ``notebook`` extra; headless runs
    embed nothing. ``width``, ``height``: pixels.
    """
    path = Path(path)
    if _interactive():
        try:
            os.environ.setdefault("RERUN_NOTEBOOK_ASSET", "inline")  # before rerun_notebook
            from rerun.notebook import Viewer

            viewer = Viewer(width=width, height=height, use_global_recording=False)
            if blueprint is not None:
                from rerun.chunk import RrdReader

                for app in {s.application_id for s in RrdReader(path).recordings()}:
                    viewer.set_application_blueprint(app, blueprint)
            viewer.display()
            viewer._viewer.send_rrd(path.read_bytes())
            return
        except Exception as exc:  # the viewer is optional: never break a run for it
            print(f"(no embedded viewer: {exc})")
    shown = shown_path(path)
    print(
        f"open the recording with: rerun {shown}   (headless or remote: rerun --web-viewer {shown})"
    )
