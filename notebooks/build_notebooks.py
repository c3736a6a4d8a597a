"""Regenerate the notebooks (``notebooks/NN_*.ipynb``, outputs stripped) from their
jupytext percent-format sources in ``notebooks/src/``.

    python notebooks/build_notebooks.py            # all
    python notebooks/build_notebooks.py 00 05      # those whose name starts so
    python notebooks/build_notebooks.py --check    # fail if an .ipynb is out of date
    NRSFM_DATA=... python notebooks/build_notebooks.py --render [00 ...]
                                                   # execute, write docs/notebooks/NN_*.md

Edit the ``src/*.py`` files, not the ``.ipynb``: these are generated (and committed so that
``pytest --nbval-lax notebooks/`` runs them).
"""

from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path

import jupytext
import nbformat

HERE = Path(__file__).resolve().parent
DOCS = HERE.parent / "docs" / "notebooks"
KERNEL = {"display_name": "Python 3", "language": "python", "name": "python3"}


#: a code cell whose first line is this has its output compared by nbval (lax mode) with
#: the output stored in the .ipynb by the last ``--render``
CHECK_MARK = "# NBVAL_CHECK_OUTPUT"
#: cells with these tags run (in the tests and the render) but are not on the rendered page:
#: the exercises' answers and the checks of what the prose says
HIDDEN = {"answers", "checks"}
#: the warning filter of every kernel the tests and ``--render`` start: a warning a
#: notebook does not catch (and explain) fails the cell
KERNEL_STARTUP = (
    "import warnings\n\nwarnings.simplefilter('error')\n"
    "# the kernel's own shutdown message (ipykernel 7), not the notebook's code\n"
    "warnings.filterwarnings('ignore', category=PendingDeprecationWarning, module='ipykernel')\n"
)


def strict_ipython_dir() -> str:
    """An IPython folder (for ``IPYTHONDIR``) whose startup file makes warnings errors."""
    import atexit
    import shutil
    import tempfile

    folder = Path(tempfile.mkdtemp(prefix="nrsfm-ipython-"))
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    startup = folder / "profile_default" / "startup"
    startup.mkdir(parents=True)
    (startup / "00-warnings-are-errors.py").write_text(KERNEL_STARTUP)
    return str(folder)


def _checked(cell) -> bool:
    return cell.cell_type == "code" and cell.source.startswith(CHECK_MARK)


def _kept_outputs(dst: Path) -> dict:
    """The stored outputs of the checked cells of ``dst``: {(id, source): outputs}."""
    if not dst.is_file():
        return {}
    nb = nbformat.read(dst, as_version=4)
    return {(c.id, c.source): c.outputs for c in nb.cells if _checked(c) and c.outputs}


def build(src: Path, outputs: dict | None = None) -> tuple[Path, str]:
    """The .ipynb of ``src`` (path, text): outputs stripped, except those of the checked
    cells (``CHECK_MARK``), taken from ``outputs`` or else from the committed .ipynb when
    the cell's source is unchanged."""
    dst = HERE / f"{src.stem}.ipynb"
    kept = _kept_outputs(dst) if outputs is None else outputs
    nb = jupytext.read(src, fmt="py:percent")
    nb.metadata = {"kernelspec": KERNEL, "language_info": {"name": "python"}}
    for i, cell in enumerate(nb.cells):
        cell.id = f"{src.stem[:2]}-{i:02d}"  # deterministic ids: stable diffs
        cell.metadata = {k: v for k, v in cell.metadata.items() if k == "tags"}
        if cell.cell_type == "code":
            cell.outputs, cell.execution_count = [], None
            if _checked(cell):
                cell.outputs = kept.get((cell.id, cell.source), [])
                if cell.outputs:  # nbval compares only cells marked as run
                    cell.execution_count = i + 1
    text = nbformat.writes(nb, version=4) + "\n"
    return dst, text


def _clean(outputs):
    """Outputs as stored: no execution counts or metadata that change between runs."""
    kept = []
    for out in outputs:
        out = nbformat.from_dict(dict(out))
        if "execution_count" in out:
            out.execution_count = None
        if "metadata" in out:
            out.metadata = {}
        kept.append(out)
    return kept


def source_hash(src: Path) -> str:
    """sha256 of a notebook source: the rendered page records it, the tests compare."""
    return hashlib.sha256(src.read_bytes()).hexdigest()


def render(src: Path, timeout: int = 1200) -> Path:
    """Execute the notebook of ``src`` (kernel in notebooks/, no embedded viewer) and write
    it as markdown with its figures to ``docs/notebooks/<name>.md`` + ``<name>_files/``."""
    import shutil

    import nbformat
    from nbclient import NotebookClient
    from nbconvert import MarkdownExporter
    from nbconvert.preprocessors import TagRemovePreprocessor

    _, text = build(src, outputs={})
    nb = nbformat.reads(text, as_version=4)
    os.environ["NRSFM_VIEWER"] = "0"  # inherited by the kernel
    os.environ["IPYTHONDIR"] = strict_ipython_dir()  # warnings are errors, as in the tests
    # the kernel runs in notebooks/: import this checkout's packages, absolute paths
    entries = [str(HERE.parent)] + [
        str(Path(p).resolve()) for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p
    ]
    os.environ["PYTHONPATH"] = os.pathsep.join(dict.fromkeys(entries))
    NotebookClient(
        nb, timeout=timeout, kernel_name="python3", resources={"metadata": {"path": str(HERE)}}
    ).execute()
    exporter = MarkdownExporter()
    exporter.register_preprocessor(TagRemovePreprocessor(remove_cell_tags=HIDDEN), enabled=True)
    body, res = exporter.from_notebook_node(nb, resources={"output_files_dir": f"{src.stem}_files"})
    DOCS.mkdir(parents=True, exist_ok=True)
    shutil.rmtree(DOCS / f"{src.stem}_files", ignore_errors=True)
    for name, data in res.get("outputs", {}).items():
        out = DOCS / name
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_bytes(data)
    body = body.replace(str(HERE.parent) + os.sep, "")  # no machine paths in the docs
    body = body.replace("](../docs/notebooks/", "](")  # images beside the rendered page
    head = (
        f"<!-- rendered by `python notebooks/build_notebooks.py --render` from "
        f"notebooks/src/{src.name} sha256={source_hash(src)}; do not edit -->\n\n"
    )
    page = DOCS / f"{src.stem}.md"
    page.write_text(head + body)
    outputs = {(c.id, c.source): _clean(c.outputs) for c in nb.cells if _checked(c)}
    dst, text = build(src, outputs=outputs)
    dst.write_text(text)  # the checked cells' outputs, for nbval to compare
    return page


def main(argv):
    check = "--check" in argv
    do_render = "--render" in argv
    prefixes = [a for a in argv if not a.startswith("--")]
    stale = []
    for src in sorted((HERE / "src").glob("[0-9][0-9]_*.py")):
        if prefixes and not any(src.stem.startswith(p) for p in prefixes):
            continue
        if do_render:
            page = render(src)
            print(f"wrote {page.relative_to(HERE.parent)}")
            continue
        dst, text = build(src)
        if check:
            if not dst.is_file() or dst.read_text() != text:
                stale.append(dst.name)
            continue
        dst.write_text(text)
        print(f"wrote {dst.relative_to(HERE.parent)}")
    if stale:
        print("out of date (run python notebooks/build_notebooks.py):", ", ".join(stale))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
