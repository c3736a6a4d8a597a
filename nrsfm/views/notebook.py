"""Notebook display and output locations: where notebooks and scripts write files, how a
path is shown, and an embedded Rerun viewer in a live notebook."""

from __future__ import annotations

from pathlib import Path

__all__ = ["output_path", "shown_path", "show_recording"]


def output_path(name, subdir="notebooks"):
    """Where notebooks and scripts write files: ``output_dir(subdir) / name``, i.e. under
    ``$NRSFM_OUT`` if set, else ``out/<subdir>/`` in the folder the user started in (never
    inside the installed package). The folder is created."""
    from ..paths import output_dir

    return output_dir(subdir) / name


def shown_path(path):
    """``path`` relative to the folder the user started in when it lies below it (for
    messages and rendered notebooks), else as given."""
    from ..paths import user_folder

    path = Path(path)
    try:
        return path.resolve().relative_to(user_folder().resolve())
    except ValueError:
        return path


def _interactive():
    """Whether a notebook front end will show an embedded viewer.

    ``NRSFM_VIEWER=1`` forces it, ``NRSFM_VIEWER=0`` (or ``NRSFM_NO_VIEWER``, ``CI``, a
    pytest run) turns it off. Otherwise: an IPython kernel started by a Jupyter server
    (JupyterLab, Notebook: ``JPY_SESSION_NAME`` set) or by VS Code. A kernel run by
    ``jupyter nbconvert --execute`` has no front end: it only prints the path.
    """
    import os
    import sys

    flag = os.environ.get("NRSFM_VIEWER")
    if flag in ("0", "1"):
        return flag == "1"
    if os.environ.get("CI") or os.environ.get("PYTEST_CURRENT_TEST") or os.environ.get(
            "NRSFM_NO_VIEWER"):
        return False
    ipy = sys.modules.get("IPython")
    shell = ipy.get_ipython() if ipy is not None else None
    if shell is None or getattr(shell, "kernel", None) is None:
        return False
    return bool(os.environ.get("JPY_SESSION_NAME") or os.environ.get("VSCODE_PID"))


def _offline_widget_assets():
    """Make rerun-notebook inline its viewer (JS + wasm) instead of loading it from the web,
    unless the user chose otherwise with ``RERUN_NOTEBOOK_ASSET``. Must run before
    ``rerun_notebook`` is imported."""
    import os

    os.environ.setdefault("RERUN_NOTEBOOK_ASSET", "inline")


def show_recording(path, width=1000, height=720, blueprint=None):
    """Embed a viewer of the ``.rrd`` at ``path`` in a live notebook; else print how to open it.

    The file is sent to the embedded viewer as it is, so the viewer shows the recording
    with its blueprint under the recording's own application id. The viewer's code is
    inlined from the installed ``rerun-notebook`` package (works offline; set
    ``RERUN_NOTEBOOK_ASSET`` to override). Needs the ``notebook`` extra. Headless runs
    (``CI``, pytest, ``jupyter nbconvert --execute``; see :func:`_interactive`) embed
    nothing.
    ``width``, ``height``: pixels.
    ``blueprint``: an optional layout that replaces the recording's own.
    Returns True when a viewer was embedded.
    """
    path = Path(path)
    if _interactive():
        try:
            _offline_widget_assets()
            from rerun.notebook import Viewer

            viewer = Viewer(width=width, height=height, use_global_recording=False)
            if blueprint is not None:
                from rerun.chunk import RrdReader

                app_ids = {s.application_id for s in RrdReader(path).recordings()}
                for app in app_ids:
                    viewer.set_application_blueprint(app, blueprint)
            viewer.display()
            viewer._viewer.send_rrd(path.read_bytes())
            return True
        except Exception as exc:  # viewer is optional: never break a run for it
            print(f"(no embedded viewer: {exc})")
    shown = shown_path(path)
    print(f"open the recording with: rerun {shown}   (headless or remote: rerun --web-viewer "
          f"{shown})")
    return False
