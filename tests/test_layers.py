"""The layers of docs/architecture.md, read from the code: every import of a module of
``nrsfm`` (at the top or inside a function) points to its own layer or a lower one, there
is no import circle between modules."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: the layers, lowest first (docs/architecture.md); a module belongs to the first prefix
#: that names it
LAYERS = [
    (
        "shared",
        [
            "nrsfm.geometry",
            "nrsfm.linalg",
            "nrsfm.validation",
            "nrsfm.io",
            "nrsfm.paths",
            "nrsfm.published",
            "nrsfm.sequence",
            "nrsfm.noise",
            "nrsfm.warnings_catalog",
        ],
    ),
    ("stages", ["nrsfm.stages"]),
    ("metrics", ["nrsfm.metrics"]),
    ("diagnostics", ["nrsfm.diagnostics"]),
    ("settings", ["nrsfm.settings"]),
    ("pipeline", ["nrsfm.pipeline"]),
    ("library glue and views", ["nrsfm.tracks", "nrsfm.views"]),
    ("package face", ["nrsfm"]),
    ("CLI and experiments", ["nrsfm.experiments", "nrsfm.cli", "nrsfm.__main__"]),
]


def _module_name(path):
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _modules():
    return {_module_name(p): p for p in (ROOT / "nrsfm").rglob("*.py")}


def _imports(name, path, known):
    """The nrsfm modules that ``name`` imports (resolved to the longest known module)."""
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = package.split(".")
            if node.level:
                base = base[: len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            targets = [f"{mod}.{a.name}" for a in node.names] + [mod]
        else:
            continue
        for t in targets:
            while t and t not in known:
                t = t.rpartition(".")[0]
            if t and t != name:
                out.add(t)
    return out


def _layer(name):
    for i, (_, prefixes) in enumerate(LAYERS):
        if any(name == p or name.startswith(p + ".") for p in prefixes):
            return i
    raise AssertionError(f"{name} is in no layer of LAYERS (add it, and to the docs)")


@pytest.fixture(scope="module")
def graph():
    mods = _modules()
    return {n: _imports(n, p, mods) for n, p in mods.items()}


def test_every_import_points_to_its_layer_or_below(graph):
    up = [
        f"{a} ({LAYERS[_layer(a)][0]}) -> {b} ({LAYERS[_layer(b)][0]})"
        for a, deps in graph.items()
        for b in deps
        if _layer(b) > _layer(a)
    ]
    assert not up, "imports that point up a layer:\n" + "\n".join(sorted(up))


def test_no_import_circle(graph):
    # a package's face importing its own modules is the package, not a circle
    edges = {a: {b for b in deps if not a.startswith(b + ".")} for a, deps in graph.items()}
    state, circles = {}, []

    def visit(n, path):
        state[n] = "open"
        for m in sorted(edges.get(n, ())):
            if state.get(m) == "open":
                circles.append(" -> ".join(path[path.index(m) :] + [m]))
            elif m not in state:
                visit(m, path + [m])
        state[n] = "done"

    for n in sorted(edges):
        if n not in state:
            visit(n, [n])
    assert not circles, "import circles:\n" + "\n".join(circles)
