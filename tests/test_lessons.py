"""The notebooks written as lessons: their structure, and every number their prose states
found in what their code printed (on the rendered page, ``docs/notebooks/``).

A lesson has a header (what you will learn, prerequisites, the paper's section), small
code cells, a summary, two or three exercises whose answers a hidden cell checks, all its
asserts in one checks cell at the end, and at least one cell whose output CI compares
(``# NBVAL_CHECK_OUTPUT``, stored by ``build_notebooks.py --render``).
"""

import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: every notebook is a lesson
LESSONS = sorted(p.stem for p in (ROOT / "notebooks" / "src").glob("[0-9][0-9]_*.py"))
MAX_CELL_LINES = 25
#: prose that cites rather than states a number (equations, sections, figures, notebooks)
_REF = r"\(?\d+(?:\.\d+)*[a-z]?\)?"
CITATION = re.compile(
    r"(Eqs?\.|Secs?\.|Figs?\.|Tables?|Algorithm|[Nn]otebooks?|[Ll]essons?|ECCV|CVPR|PAMI"
    r"|NIPS|ICCV|et al\.,?)\s*" + _REF + r"(?:\s*(?:-|,|and|\()\s*[a-z]?" + _REF + r"\)?)*"
)
NUMBER = re.compile(r"(?<![\w.])-?\d+(?:\.\d+)?(?:e[-+]?\d+)?(?![\w.])")


def _cells(name):
    return json.loads((ROOT / "notebooks" / f"{name}.ipynb").read_text())["cells"]


def _source(cell):
    return "".join(cell["source"])


def _tags(cell):
    return cell.get("metadata", {}).get("tags", [])


@pytest.mark.parametrize("name", LESSONS)
def test_lesson_structure(name):
    cells = _cells(name)
    head = _source(cells[0])
    for part in ("What you will learn", "Prerequisites", "Paper"):
        assert part in head, (name, part)
    assert "$$" not in head, "the intuition and a picture come before the formulas"
    prose = "\n".join(_source(c) for c in cells if c["cell_type"] == "markdown")
    assert "## Summary" in prose and "## Exercises" in prose
    exercises = prose.split("## Exercises", 1)[1]
    assert 2 <= len(re.findall(r"^\d\. ", exercises, re.M)) <= 3
    code = [c for c in cells if c["cell_type"] == "code"]
    for cell in code:
        assert len(_source(cell).splitlines()) <= MAX_CELL_LINES, _source(cell)[:80]
    checks = [c for c in code if "checks" in _tags(c)]
    assert len(checks) == 1 and code[-1] is checks[0], "one checks cell, the last"
    for cell in code:
        if cell is not checks[0] and "answers" not in _tags(cell):
            assert not re.search(r"^\s*assert\b", _source(cell), re.M), _source(cell)[:80]
    assert any("answers" in _tags(c) for c in code), "the exercises' answers are checked"
    compared = [c for c in code if _source(c).startswith("# NBVAL_CHECK_OUTPUT")]
    assert compared and all(c["outputs"] for c in compared), "a compared output, stored"
    assert not re.search(r"issue \d|nrsfm\.research", prose + "".join(map(_source, code)))


def _page_parts(name):
    """(prose, outputs) of the rendered page: Markdown outside code blocks and outputs."""
    text = (ROOT / "docs" / "notebooks" / f"{name}.md").read_text()
    text = re.sub(r"```.*?```", "", text, flags=re.S)  # the code cells
    prose, outputs = [], []
    for line in text.splitlines():
        (outputs if line.startswith("    ") else prose).append(line)
    return "\n".join(prose), "\n".join(outputs)


def _stated_numbers(prose):
    prose = re.sub(r"\$\$.*?\$\$|\$[^$]*\$|`[^`]*`|\([^()]*\.(png|md)\)", " ", prose, flags=re.S)
    prose = re.sub(r"<!--.*?-->|!\[[^\]]*\]\([^)]*\)", " ", prose, flags=re.S)
    prose = re.sub(r"^#+ \d\d ·", "", prose, flags=re.M)  # the lesson's own number
    prose = CITATION.sub(" ", prose)
    return NUMBER.findall(prose)


def _found(value, outputs):
    """Whether ``value`` (as written) is among the printed numbers, to its precision."""
    decimals = len(value.split(".")[1].split("e")[0]) if "." in value else 0
    x = float(value)
    for printed in NUMBER.findall(outputs):
        y = float(printed)
        if y == x or ("e" not in value and round(y, decimals) == x):
            return True
    return False


@pytest.mark.parametrize("name", LESSONS)
def test_every_number_in_the_prose_was_printed(name):
    prose, outputs = _page_parts(name)
    missing = [v for v in _stated_numbers(prose) if not _found(v, outputs)]
    assert missing == [], f"{name}: numbers in the prose that no output shows: {missing}"


@pytest.mark.parametrize("name", LESSONS)
def test_no_stray_output(name):
    _, outputs = _page_parts(name)
    assert not re.search(r"^    (False|True|None)$", outputs, re.M)
    assert "Warning:" not in outputs
