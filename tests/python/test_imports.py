"""The import graphs of python/volrig and addon/volrig_addon have no cycle, counting every intra-package import
(at module top and inside functions), and no module of volrig reads the shared data (../shared/data belongs to the
tests: tests/support/volrig_support)."""
import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PACKAGES = {"volrig": REPO / "python" / "volrig", "volrig_addon": REPO / "addon" / "volrig_addon"}


def modules(folder: Path):
    """Module name (the file's stem; "__init__" for the package) -> path, for every .py file of a package."""
    return {p.stem: p for p in sorted(folder.glob("*.py"))}


def edges(package: str, folder: Path):
    """(importer, imported) for every import of one module of the package by another, wherever it is written:
    ``import pkg.x``, ``from . import x``, ``from .x import y``, ``from pkg.x import y``, ``from pkg import x``."""
    names = modules(folder)
    native = {p.name.split(".")[0] for p in folder.iterdir() if p.suffix in (".so", ".pyd")}  # _volrig: no imports
    found = set()
    for name, path in names.items():
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            targets = []
            if isinstance(node, ast.Import):
                for alias in node.names:
                    parts = alias.name.split(".")
                    if parts[0] == package:
                        targets.append(parts[1] if len(parts) > 1 else "__init__")
            elif isinstance(node, ast.ImportFrom):
                if node.level > 1:
                    continue  # above the package
                parts = node.module.split(".") if node.module else []
                if node.level == 0:
                    if not parts or parts[0] != package:
                        continue
                    parts = parts[1:]
                if parts:
                    targets.append(parts[0])
                else:  # from . import x / from pkg import x: a submodule (maybe compiled), or a name of __init__
                    targets += [a.name if a.name in names or a.name in native else "__init__" for a in node.names]
            for t in targets:
                if t in names and t != name:
                    found.add((name, t))
    return names, found


def find_cycle(nodes, graph_edges):
    """One cycle as a list of modules (first == last), or None."""
    out = {n: sorted(b for a, b in graph_edges if a == n) for n in nodes}
    state, stack = {}, []

    def visit(n):
        state[n] = "open"
        stack.append(n)
        for m in out[n]:
            if state.get(m) == "open":
                return stack[stack.index(m):] + [m]
            if m not in state:
                cycle = visit(m)
                if cycle:
                    return cycle
        stack.pop()
        state[n] = "done"
        return None

    for n in sorted(nodes):
        if n not in state:
            cycle = visit(n)
            if cycle:
                return cycle
    return None


# __init__ imports its submodules; a submodule importing the package's __init__ (``from volrig import Volume``)
# would close a cycle through it, and is counted.
@pytest.mark.parametrize("package", sorted(PACKAGES))
def test_no_import_cycle(package):
    names, found = edges(package, PACKAGES[package])
    assert len(names) > 5 and found, f"no modules or imports found in {PACKAGES[package]}"
    cycle = find_cycle(names, found)
    assert cycle is None, f"{package} imports in a circle: {' -> '.join(cycle)}"


def test_cycle_finder_finds_cycles():
    assert find_cycle(["a", "b", "c"], {("a", "b"), ("b", "c")}) is None
    assert find_cycle(["a", "b", "c"], {("a", "b"), ("b", "c"), ("c", "a")}) == ["a", "b", "c", "a"]


def test_edges_count_imports_inside_functions(tmp_path):
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("from . import a\n")
    (pkg / "a.py").write_text("def f():\n    from .b import g\n    return g\n")
    (pkg / "b.py").write_text("import pkg.c\n")
    (pkg / "c.py").write_text("def h():\n    from pkg import a\n")
    names, found = edges("pkg", pkg)
    assert found == {("__init__", "a"), ("a", "b"), ("b", "c"), ("c", "a")}
    assert find_cycle(names, found) == ["a", "b", "c", "a"]


def test_volrig_does_not_read_shared_data():
    for path in sorted(PACKAGES["volrig"].glob("*.py")):
        text = path.read_text()
        for needle in ("shared/data", "../shared"):
            assert needle not in text, f"{path.relative_to(REPO)} names {needle}: the shared data are the tests'"
