"""The documentation site's sources: every public name has an API page, every lesson and
every hand-written page is reachable from a table of contents."""

import re
from pathlib import Path

import data_tools
import nrsfm

DOCS = Path(__file__).resolve().parents[1] / "docs"


def _toctree_entries():
    entries = set()
    for page in DOCS.rglob("*.md"):
        for block in re.findall(r"```\{toctree\}\n(.*?)```", page.read_text(), re.S):
            base = page.parent.relative_to(DOCS)
            for line in block.splitlines():
                if line.strip() and not line.startswith(":"):
                    entries.add((base / line.strip()).as_posix())
    return entries


def test_every_public_name_has_an_api_entry():
    api = (DOCS / "api.rst").read_text()
    listed = {}
    for module, block in re.findall(
        r"\.\. currentmodule:: (\w+)\n\n\.\. autosummary::\n   :toctree: generated\n\n"
        r"((?:   \w+\n)+)",
        api,
    ):
        listed.setdefault(module, []).extend(block.split())
    for module in (nrsfm, data_tools):
        public = sorted(n for n in module.__all__ if not n.startswith("__"))
        assert sorted(listed[module.__name__]) == public, module.__name__


def test_every_page_is_in_a_table_of_contents():
    entries = _toctree_entries() | {"index", "api"}
    pages = {
        p.relative_to(DOCS).with_suffix("").as_posix()
        for p in DOCS.rglob("*.md")
        if "_files" not in p.parts[-2] and p.parts[len(DOCS.parts)] not in ("generated",)
    }
    assert pages - entries == set()
    assert "api" in (DOCS / "reference.md").read_text()
