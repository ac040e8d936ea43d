#!/usr/bin/env python3
"""tests/check_layout.py: one capability, one name at every layer, native code and Python package.

For every capability in CAPABILITIES (the one list of them) it checks that
  native/src/<cap>/                 holds the capability's sources,
  native/include/volrig/<cap>.hpp   is its public header,
  native/bindings/<cap>.cpp         is its binding file,
  tests/native/test_<cap>*.cpp      holds at least one of its Catch2 test files (test_<cap>.cpp or test_<cap>_<stage>.cpp),
  python/volrig/<cap>.py            is its Python module (or python/volrig/<cap>/, a subpackage),
  tests/python/test_<cap>*.py       holds at least one of its pytest files (test_<cap>.py or test_<cap>_<stage>.py),
and, across the tree, that
  - no .cpp lies loose in native/src (the shared helpers live in native/src/common/, see COMMON below);
  - every folder of native/src, public header, binding file and Catch2 test file belongs to a capability by its name
    (or is one of the shared ones listed here);
  - every internal namespace of native/src/<cap>/ is volrig::<cap>_detail (common/: volrig::common_detail);
  - no source file of native/ or tests/native/ is over MAX_FILE_LINES lines, and no C++ function of native/ over
    MAX_FUNCTION_LINES lines (a rough brace-matching count: comments and strings stripped, a function is a brace block opened after a
    parenthesised signature at namespace or class level; lambdas count inside their function);
  - no Python file of PYTHON_FOLDERS (the package, the add-on, the Python tests and their support, the scripts and
    the benchmarks) is over MAX_FILE_LINES lines either: its .py files, and in scripts/ also the extensionless
    scripts run by python3 (their first line says so); nor any Python function over MAX_FUNCTION_LINES lines (its
    whole definition, by the ast);
  - every module and subpackage of python/volrig belongs to a capability (its "python" list), is one of the shared
    and pipeline modules of SHARED_MODULES (each with the reason it belongs to no one capability), or is an old name
    kept for compatibility (ALIASES);
  - every tests/python/test_<name>*.py is named after a capability, one of its Python modules or test stages
    ("python_tests"), a shared module, or is one of PROJECT_TESTS (tests of the repository as a whole).

Where the Python modules are not named as the capability, CAPABILITIES says so ("python"):
  - io: `volume.py` (Volume, load, save, dicom_series, write_vdb) and `files.py` (atomic_output): public module
    names (`volrig.volume.Volume`, the type every capability's API takes) that an io.py would break. io's pytest
    files are test_io_<format>.py, as the native side's test_io_<format>.cpp.
  - rig: `markers.py`, `bones.py` (rigs from a scan's bones) and `rigfile.py` (the .vrig file) beside `rig.py`;
    deform: `rigid_layer.py` beside `deform.py`. They keep their module names, which are public
    (`volrig.markers`, ...), rather than move into subpackages.

Plain Python, no dependencies: `python3 tests/check_layout.py` prints the problems and exits 1 when there are any
(tests/python/test_layout.py runs it).
"""
from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SRC = REPO / "native" / "src"
INCLUDE = REPO / "native" / "include" / "volrig"
BINDINGS = REPO / "native" / "bindings"
TESTS = REPO / "tests" / "native"
PACKAGE = REPO / "python" / "volrig"
PY_TESTS = REPO / "tests" / "python"

# The capabilities, in the order the module binds them. "headers": further public headers of the capability, besides
# <cap>.hpp (they declare one stage each and are kept so that includes stay small). "python": its modules (or
# subpackages) of python/volrig when they are not just <cap> (the module docstring says why); "python_tests": further
# stems of its tests/python/test_<stem>*.py files, besides <cap> and its modules' names.
CAPABILITIES: dict[str, dict[str, list[str]]] = {
    # volume readers and writers (NRRD, NIfTI, MetaImage, DICOM, TIFF, VDB, raw), zlib
    "io": {"headers": [], "python": ["volume", "files"]},
    "skeleton": {"headers": ["distance.hpp", "components.hpp", "reconstruct.hpp"]},  # DT, thinness skeleton
    "medial": {"headers": ["medial_surface.hpp", "thickness.hpp"]},  # plane measure, medial surface, thickness
    "tree": {"headers": []},  # the skeleton-tree
    # autorig (rig/autorig/), bind, rest matrices, rigs from the bones (rig/bones/)
    "rig": {"headers": [], "python": ["rig", "markers", "bones", "rigfile"]},
    "skin": {"headers": []},  # skin weights
    "mesh": {"headers": []},  # mesh readers and writers, voxelize
    "deform": {"headers": [], "python": ["deform", "rigid_layer"]},
    "mocap": {"headers": []},  # motion capture: the BVH reader (native), retargeting and animation (Python)
    "centerline": {"headers": []},
    "collide": {"headers": []},
    "drawing": {"headers": []},  # drawings: PNG reading (native), inflation to a solid (Python)
    "track": {"headers": []},  # feature tracking over time steps: features and point overlaps (native), events (Python)
    "pores": {"headers": []},  # pore networks of rock (thesis 9.4): extraction, flow (native), OpenPNM files (Python)
}

# Modules of python/volrig that belong to no one capability: the package's front, the pipeline that chains the
# capabilities, and what several of them share.
SHARED_MODULES = {
    "__init__": "the package: every capability's functions re-exported as volrig.<name>",
    "__main__": "python -m volrig",
    "cli": "the command line, over the pipeline",
    "cli_commands": "the command line's commands (cli.py keeps the argument parser and main): one file of 800 "
                    "lines would not hold both",
    "pipeline": "the steps chained from a file to baked frames, for the CLI, the add-on and the demo",
    "demo": "the README's demo",
    "_optional": "scipy is optional: the numpy fallbacks several capabilities use",
    "segment": "segmentation, from a volume to the mask every capability starts from (numpy, no native part)",
    "phantom": "the procedural humanoid, data for tests, demos and benchmarks",
    "walk": "a procedural walk cycle for humanoid rigs, motion for demos, tests and the add-on",
    "parts": "looks by rig part and exploded views, over a rig, a binding and the deformer",
    "tissues": "looks by tissue class of label maps, for bakes",
}
# Old module names kept so that existing imports keep working, and the module they stand for.
ALIASES = {"centerlines": "centerline"}
# tests/python files of the repository as a whole (test_<name>.py), not of one module.
PROJECT_TESTS = {
    "layout": "this check",
    "docs": "the paths the docs name exist",
    "project": "pyproject.toml's metadata, the linters",
    "imports": "no import cycles; no module of the package reads the shared data",
    "wheel": "the wheel in a bare Debian root",
    "flamenco_job": "farm/flamenco's job type",
    "subjects": "tests/support's shared subjects",
    "armature_data": "what the add-on stores (armatures, vertex groups, VDB) read back without Blender",
}

# Shared by every capability: native/src/common/ (volume.cpp: the Grid of volume.hpp; memory.cpp: the pools of
# memory.hpp; ball_scan.hpp: painting balls, for reconstruct and thickness; neighbourhood.hpp: the 26-neighbourhood,
# for distance, components and skin; point_grid.hpp: a bucket grid of points and disjoint sets, for tree and autorig)
# and the public headers every capability's API is written in.
COMMON = "common"
COMMON_HEADERS = ["volume.hpp", "memory.hpp", "error.hpp", "progress.hpp"]
LOOSE_SOURCES: list[str] = []  # .cpp files allowed directly in native/src: none
MODULE_BINDING = "module.cpp"  # the module itself: exceptions, then each capability's bind_<cap>
BINDING_HELPERS = ["convert.hpp"]

MAX_FILE_LINES = 800
MAX_FUNCTION_LINES = 100
# The folders whose Python files MAX_FILE_LINES holds for too (with their subfolders).
PYTHON_FOLDERS = ["python/volrig", "addon/volrig_addon", "tests/python", "tests/support", "scripts", "benchmarks"]


def _stem_matches(stem: str, cap: str) -> bool:
    return stem == cap or stem.startswith(cap + "_")


def owner(stem: str) -> str | None:
    """The capability a file stem (`<cap>` or `<cap>_<stage>`) belongs to: the longest capability name it starts with."""
    hits = [c for c in list(CAPABILITIES) + [COMMON] if _stem_matches(stem, c)]
    return max(hits, key=len) if hits else None


def _strip(src: str) -> str:
    """C++ source with comments, strings and character literals blanked (newlines kept)."""
    src = re.sub(r"//[^\n]*", "", src)
    src = re.sub(r"/\*.*?\*/", lambda m: "\n" * m.group().count("\n"), src, flags=re.S)
    src = re.sub(r'R"([^(\s]*)\((.*?)\)\1"', lambda m: '""' + "\n" * m.group().count("\n"), src, flags=re.S)
    src = re.sub(r'"(\\.|[^"\\\n])*"', '""', src)
    src = re.sub(r"'(\\.|[^'\\\n])*'", "''", src)
    return src


def functions(path: Path) -> list[tuple[int, int, str]]:
    """(lines, first line, signature tail) of each function defined in a C++ file."""
    text = _strip(path.read_text(encoding="utf-8"))
    stack: list[tuple[str, int, str]] = []
    head, line, out = "", 1, []
    for ch in text:
        if ch == "\n":
            line += 1
        if ch == "{":
            h = head.strip()
            parent = stack[-1][0] if stack else "scope"
            kind = "block"
            if re.search(r"\bnamespace\b", h) or re.search(r"\b(class|struct|union|enum)\b[^()]*$", h):
                kind = "scope"
            elif (parent == "scope" and "(" in h and not re.match(r"(if|for|while|switch|catch|do|else)\b", h)
                  and not h.endswith("=")):
                kind = "function"
            stack.append((kind, line, " ".join(h.split())[-60:]))
            head = ""
        elif ch == "}":
            if stack:
                kind, first, sig = stack.pop()
                if kind == "function":
                    out.append((line - first + 1, first, sig))
            head = ""
        elif ch == ";":
            head = ""
        else:
            head += ch
    return out



def rel(p: Path) -> str:
    return p.relative_to(REPO).as_posix()


def native_problems() -> list[str]:
    out: list[str] = []

    # Each capability: folder, header, binding, tests.
    for cap, extra in CAPABILITIES.items():
        folder = SRC / cap
        if not folder.is_dir() or not any(folder.rglob("*.cpp")):
            out.append(f"{cap}: no sources in native/src/{cap}/")
        for h in [f"{cap}.hpp"] + extra["headers"]:
            if not (INCLUDE / h).is_file():
                out.append(f"{cap}: no public header native/include/volrig/{h}")
        if not (BINDINGS / f"{cap}.cpp").is_file():
            out.append(f"{cap}: no binding file native/bindings/{cap}.cpp")
        if not [p for p in TESTS.glob("test_*.cpp") if owner(p.stem[len("test_"):]) == cap]:
            out.append(f"{cap}: no Catch2 tests tests/native/test_{cap}.cpp or test_{cap}_<stage>.cpp")

    # Nothing outside the mapping.
    for p in sorted(SRC.glob("*")):
        if p.is_file() and p.suffix == ".cpp" and p.name not in LOOSE_SOURCES:
            out.append(f"{rel(p)}: a loose source; move it into its capability's folder")
        elif p.is_file():
            out.append(f"{rel(p)}: a loose file; move it into its capability's folder or native/src/common/")
        elif p.is_dir() and p.name not in CAPABILITIES and p.name != COMMON:
            out.append(f"{rel(p)}/: a folder that is no capability (add it to CAPABILITIES or move its files)")
    extra_headers = {h for e in CAPABILITIES.values() for h in e["headers"]}
    for p in sorted(INCLUDE.glob("*.hpp")):
        if p.stem not in CAPABILITIES and p.name not in extra_headers and p.name not in COMMON_HEADERS:
            out.append(f"{rel(p)}: a public header of no capability")
    for p in sorted(BINDINGS.glob("*")):
        if p.name == MODULE_BINDING or p.name in BINDING_HELPERS:
            continue
        if p.suffix == ".cpp" and owner(p.stem) not in CAPABILITIES:
            out.append(f"{rel(p)}: a binding file of no capability (name it <cap>.cpp or <cap>_<stage>.cpp)")
    for p in sorted(TESTS.glob("*.cpp")):
        if p.name == "main.cpp":
            continue
        if not p.stem.startswith("test_") or owner(p.stem[len("test_"):]) is None:
            out.append(f"{rel(p)}: a Catch2 file of no capability (name it test_<cap>.cpp or test_<cap>_<stage>.cpp)")

    # One internal namespace convention: volrig::<cap>_detail.
    decl = re.compile(r"\bnamespace\s+([A-Za-z_][\w:]*)\s*\{")
    for p in sorted(SRC.rglob("*.[ch]pp")):
        cap = p.relative_to(SRC).parts[0]
        allowed = {"volrig", f"volrig::{cap}_detail", f"{cap}_detail"}
        for name in decl.findall(_strip(p.read_text(encoding="utf-8"))):
            if name not in allowed:
                out.append(f"{rel(p)}: namespace {name} (internal namespaces are volrig::{cap}_detail)")

    # Sizes (Catch2's own single header, tests/native/catch2_v3, aside).
    tests = [p for p in TESTS.glob("*.[ch]pp")]
    for p in sorted((REPO / "native").rglob("*.[ch]pp")) + sorted(tests):
        n = len(p.read_text(encoding="utf-8").splitlines())
        if n > MAX_FILE_LINES:
            out.append(f"{rel(p)}: {n} lines (at most {MAX_FILE_LINES})")
        if p in tests:
            continue
        for lines, first, sig in functions(p):
            if lines > MAX_FUNCTION_LINES:
                out.append(f"{rel(p)}:{first}: a function of {lines} lines (at most {MAX_FUNCTION_LINES}): {sig}")
    return out


def python_files() -> list[Path]:
    """The Python files of PYTHON_FOLDERS: every .py file, and the extensionless scripts whose first line runs
    python (scripts/extension)."""
    out = []
    for folder in PYTHON_FOLDERS:
        for p in sorted((REPO / folder).rglob("*")):
            if not p.is_file() or "__pycache__" in p.parts:
                continue
            if p.suffix == ".py":
                out.append(p)
            elif not p.suffix:
                with p.open("rb") as f:
                    first = f.readline()
                if first.startswith(b"#!") and b"python" in first:
                    out.append(p)
    return out


def python_modules(cap: str) -> list[str]:
    """The modules (or subpackages) of python/volrig that make up a capability."""
    return CAPABILITIES[cap].get("python", [cap])


def package_modules() -> list[str]:
    """The modules (`name.py`) and subpackages (`name/__init__.py`) of python/volrig, by name."""
    mods = [p.stem for p in PACKAGE.glob("*.py")]
    mods += [p.name for p in PACKAGE.iterdir() if p.is_dir() and (p / "__init__.py").is_file()]
    return sorted(mods)


def python_problems() -> list[str]:
    out: list[str] = []
    present = set(package_modules())
    tests = sorted(p.stem[len("test_"):] for p in PY_TESTS.glob("test_*.py"))

    # Each capability: its module(s) and at least one test file by its name.
    for cap in CAPABILITIES:
        for m in python_modules(cap):
            if m not in present:
                out.append(f"{cap}: no Python module python/volrig/{m}.py (or subpackage python/volrig/{m}/)")
        if not [t for t in tests if _stem_matches(t, cap)]:
            out.append(f"{cap}: no pytest file tests/python/test_{cap}.py or test_{cap}_<stage>.py")

    # Every module belongs somewhere; every alias stands for a module.
    owned = {m: cap for cap in CAPABILITIES for m in python_modules(cap)}
    for m in sorted(present):
        if m not in owned and m not in SHARED_MODULES and m not in ALIASES:
            out.append(f"python/volrig/{m}: a module of no capability (name it <cap>.py, or list it in CAPABILITIES' "
                       "\"python\" or, with its reason, in SHARED_MODULES)")
    for old, new in ALIASES.items():
        if new not in present:
            out.append(f"python/volrig/{old}: an alias of {new}, which is no module")
    for m in SHARED_MODULES:
        if m in owned:
            out.append(f"python/volrig/{m}: listed both as shared and as {owned[m]}'s")

    # Sizes: files, and functions (their whole definition, decorators and docstring included).
    for p in python_files():
        text = p.read_text(encoding="utf-8")
        n = len(text.splitlines())
        if n > MAX_FILE_LINES:
            out.append(f"{rel(p)}: {n} lines (at most {MAX_FILE_LINES})")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = node.end_lineno - node.lineno + 1
                if lines > MAX_FUNCTION_LINES:
                    out.append(f"{rel(p)}:{node.lineno}: a function of {lines} lines (at most {MAX_FUNCTION_LINES}): "
                               f"{node.name}")

    # Every test file is named after what it tests.
    names = set(CAPABILITIES) | set(owned) | {m.lstrip("_") for m in SHARED_MODULES if not m.startswith("__")}
    names |= {t for e in CAPABILITIES.values() for t in e.get("python_tests", [])} | set(PROJECT_TESTS)
    for t in tests:
        if not any(_stem_matches(t, n) for n in names):
            out.append(f"tests/python/test_{t}.py: a pytest file of no capability or module (name it test_<cap>.py, "
                       "test_<cap>_<stage>.py or test_<module>.py)")
    return out


def problems() -> list[str]:
    return native_problems() + python_problems()


def main() -> int:
    found = problems()
    for p in found:
        print(p)
    print(f"check_layout: {len(CAPABILITIES)} capabilities, {len(package_modules())} Python modules, "
          f"{len(found)} problem(s)")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
