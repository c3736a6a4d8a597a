"""Regenerate the notebooks (``notebooks/NN_*.ipynb``, outputs stripped) from their
jupytext percent-format sources in ``notebooks/src/``.

    python notebooks/build_notebooks.py            # all
    python notebooks/build_notebooks.py 00 05      # those whose name starts so
    python notebooks/build_notebooks.py --check    # fail if an .ipynb is out of date

Edit the ``src/*.py`` files, not the ``.ipynb``: these are generated (and committed so that
``pytest --nbval-lax notebooks/`` runs them).
"""

from __future__ import annotations

import sys
from pathlib import Path

import jupytext
import nbformat

HERE = Path(__file__).resolve().parent
KERNEL = {"display_name": "Python 3", "language": "python", "name": "python3"}


def build(src: Path) -> tuple[Path, str]:
    nb = jupytext.read(src, fmt="py:percent")
    nb.metadata = {"kernelspec": KERNEL, "language_info": {"name": "python"}}
    for i, cell in enumerate(nb.cells):
        cell.id = f"{src.stem[:2]}-{i:02d}"       # deterministic ids: stable diffs
        cell.metadata = {k: v for k, v in cell.metadata.items() if k == "tags"}
        if cell.cell_type == "code":
            cell.outputs, cell.execution_count = [], None
    text = nbformat.writes(nb, version=4) + "\n"
    return HERE / f"{src.stem}.ipynb", text


def main(argv):
    check = "--check" in argv
    prefixes = [a for a in argv if not a.startswith("--")]
    stale = []
    for src in sorted((HERE / "src").glob("[0-9][0-9]_*.py")):
        if prefixes and not any(src.stem.startswith(p) for p in prefixes):
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
