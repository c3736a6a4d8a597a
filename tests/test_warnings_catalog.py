"""Warnings and their documentation are one source: every warning or note the code issues
is built by :func:`nrsfm.warnings_catalog.text` from an id of the catalog, every id has its
entry in ``docs/warnings.md`` (written from the catalog by ``tools/warnings_doc.py``), and
every message starts with the words its entry gives."""

import ast
import importlib.util
import re
from pathlib import Path

import pytest

from nrsfm.warnings_catalog import CATALOG, UNRELIABLE, ids_in, lead, text

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "warnings.md"


def _doc_tool():
    spec = importlib.util.spec_from_file_location(
        "warnings_doc", ROOT / "tools" / "warnings_doc.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _resolver(tree):
    """``ids(node)``: the catalog ids an expression of one module can be, [] when it is not
    built by the catalog's ``text`` (a call ``text("id", ...)``, a conditional between such
    calls, or a variable assigned one)."""
    names = {
        a.asname or a.name
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom) and (node.module or "").endswith("warnings_catalog")
        for a in node.names
        if a.name == "text"
    }
    variables = {}

    def ids(node):
        if isinstance(node, ast.Call) and getattr(node.func, "id", None) in names:
            assert isinstance(node.args[0], ast.Constant), f"line {node.lineno}: id not literal"
            return [node.args[0].value]
        if isinstance(node, ast.IfExp):
            body, other = ids(node.body), ids(node.orelse)
            return body + other if body and other else []
        if isinstance(node, ast.Name):
            return variables.get(node.id, [])
        return []

    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and ids(node.value):
            variables.update(
                {t.id: ids(node.value) for t in node.targets if isinstance(t, ast.Name)}
            )
    return ids


def _issued(path):
    """(context, id or None, line) of every warning and diagnostics flag or note issued in
    one module: ``warn`` calls and ``flags`` / ``notes`` ``.append`` / ``.insert``."""
    tree = ast.parse(path.read_text())
    ids = _resolver(tree)
    out = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        f = node.func
        name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", None)
        owner = getattr(f.value, "id", None) if isinstance(f, ast.Attribute) else None
        if name == "warn" and node.args:
            ctx, arg = "warn", node.args[0]
        elif owner in ("flags", "notes") and name in ("append", "insert") and node.args:
            ctx, arg = owner, node.args[-1]
        else:
            continue
        if isinstance(arg, ast.Attribute) and arg.attr == "message" and ctx == "warn":
            continue  # Diagnostics.message: UNRELIABLE + the flags
        where = f"{path.relative_to(ROOT)}:{node.lineno}"
        out += [(ctx, wid, where) for wid in ids(arg)] or [(ctx, None, where)]
    return out


@pytest.fixture(scope="module")
def issued():
    return [x for p in sorted((ROOT / "nrsfm").rglob("*.py")) for x in _issued(p)]


def test_every_issued_warning_comes_from_the_catalog(issued):
    loose = [where for _, wid, where in issued if wid is None]
    assert not loose, (
        "warnings or notes not built by warnings_catalog.text (add an entry "
        "to CATALOG and use it): " + ", ".join(loose)
    )
    unknown = sorted({wid for _, wid, _ in issued} - set(CATALOG))
    assert not unknown, f"ids missing from the catalog: {unknown}"
    unused = sorted(set(CATALOG) - {wid for _, wid, _ in issued})
    assert not unused, f"catalog entries the code never issues: {unused}"


def test_warnings_are_W_and_notes_are_N(issued):
    wrong = [
        f"{wid} as {ctx} ({where})"
        for ctx, wid, where in issued
        if wid is not None and wid.startswith("N-") != (ctx == "notes")
    ]
    assert not wrong, "notes must be notes and warnings warnings: " + ", ".join(wrong)


def test_every_id_has_its_entry_in_the_docs():
    doc = DOC.read_text()
    sections = dict(re.findall(r"^## (\S+)\n(.*?)(?=^## |\Z)", doc, flags=re.M | re.S))
    missing = [wid for wid in CATALOG if wid not in sections]
    assert not missing, f"docs/warnings.md has no entry for {missing}"
    extra = sorted(set(sections) - set(CATALOG))
    assert not extra, f"docs/warnings.md documents ids the catalog does not have: {extra}"
    for wid, body in sections.items():
        for part in ("Trigger:", "What it means:", "What to do:"):
            assert f"**{part}**" in body, (wid, part)
        assert f"**Message starts with:** `{lead(wid)}`" in body, wid
    assert f"`{UNRELIABLE.strip()}`" in doc


def test_docs_are_written_from_the_catalog():
    assert DOC.read_text() == _doc_tool().document(), (
        "docs/warnings.md is out of date: run python tools/warnings_doc.py"
    )


@pytest.mark.parametrize("wid", sorted(CATALOG))
def test_message_starts_with_the_words_the_doc_gives(wid):
    head = lead(wid)
    assert head.startswith(f"{wid}: ") and len(head.split()) >= 2, head
    message = text(wid, **CATALOG[wid].example)
    assert message.startswith(head) and "{" not in head


def test_ids_in_names_every_flag_of_a_message():
    for wid, entry in CATALOG.items():
        assert ids_in(text(wid, **entry.example)) == [wid]
    joined = "unreliable reconstruction: " + "; ".join(
        text(w, **CATALOG[w].example) for w in ("W-few-frames", "W-camera-jumps")
    )
    assert ids_in(joined) == ["W-few-frames", "W-camera-jumps"]
    assert ids_in("a message without an id") == []
