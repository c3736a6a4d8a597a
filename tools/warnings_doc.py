"""Write ``docs/warnings.md`` from :data:`nrsfm.warnings_catalog.CATALOG`.

    python tools/warnings_doc.py           # rewrite docs/warnings.md
    python tools/warnings_doc.py --check   # exit 1 if docs/warnings.md is out of date

The thresholds the entries name are read from the modules that own them (:func:`constants`),
so the page states the values the code uses.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "warnings.md"
sys.path.insert(0, str(ROOT))


def constants():
    """Threshold name -> value, for the ``{NAME}`` fields of the catalog's triggers."""
    from nrsfm import diagnostics
    from nrsfm.cli.run import INPUT_KEYS
    from nrsfm.stages.perspective import MAX_DEPTH_RATIO
    from nrsfm.stages.shape.closed_form import NULLSPACE_GAP_MIN

    out = {name: value for name, value in vars(diagnostics).items() if name.isupper()}
    out.update(NULLSPACE_GAP_MIN=NULLSPACE_GAP_MIN, INPUT_KEYS=", ".join(INPUT_KEYS))
    out.update(MAX_DEPTH_RATIO=MAX_DEPTH_RATIO)
    out["ORTHOGRAPHIC_START_FLAGS"] = ", ".join(diagnostics.ORTHOGRAPHIC_START_FLAGS)
    return out


def document():
    """The text of ``docs/warnings.md``."""
    from nrsfm.warnings_catalog import render_markdown

    return render_markdown(constants()) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--check", action="store_true", help="only check that docs/warnings.md is up to date"
    )
    args = parser.parse_args(argv)
    text = document()
    if args.check:
        ok = DOC.exists() and DOC.read_text() == text
        print(f"{DOC.relative_to(ROOT)} is {'up to date' if ok else 'out of date'}")
        return 0 if ok else 1
    DOC.write_text(text)
    print(f"wrote {DOC.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
