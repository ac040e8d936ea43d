#!/usr/bin/env python3
"""tests/check_layout.py: one capability, one name at every layer of the native code.

For every capability in CAPABILITIES (the one list of them) it checks that
  native/src/<cap>/                 holds the capability's sources,
  native/include/volrig/<cap>.hpp   is its public header,
  native/bindings/<cap>.cpp         is its binding file,
  tests/native/test_<cap>*.cpp      holds at least one of its Catch2 test files (test_<cap>.cpp or test_<cap>_<stage>.cpp),
and, across the tree, that
  - no .cpp lies loose in native/src (the shared helpers live in native/src/common/, see COMMON below);
  - every folder of native/src, public header, binding file and Catch2 test file belongs to a capability by its name
    (or is one of the shared ones listed here);
  - every internal namespace of native/src/<cap>/ is volrig::<cap>_detail (common/: volrig::common_detail);
  - no source file of native/ or tests/native/ is over MAX_FILE_LINES lines, and no C++ function of native/ over
    MAX_FUNCTION_LINES lines (a rough brace-matching count: comments and strings stripped, a function is a brace block opened after a
    parenthesised signature at namespace or class level; lambdas count inside their function).

Plain Python, no dependencies: `python3 tests/check_layout.py` prints the problems and exits 1 when there are any
(tests/python/test_layout.py runs it).
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SRC = REPO / "native" / "src"
INCLUDE = REPO / "native" / "include" / "volrig"
BINDINGS = REPO / "native" / "bindings"
TESTS = REPO / "tests" / "native"

# The capabilities, in the order the module binds them. "headers": further public headers of the capability, besides
# <cap>.hpp (they declare one stage each and are kept so that includes stay small).
CAPABILITIES: dict[str, dict[str, list[str]]] = {
    "io": {"headers": []},  # volume readers and writers (NRRD, NIfTI, MetaImage, DICOM, TIFF, VDB, raw), zlib
    "image": {"headers": []},  # drawings: PNG reading
    "skeleton": {"headers": ["distance.hpp", "components.hpp", "reconstruct.hpp"]},  # DT, thinness skeleton
    "medial": {"headers": ["medial_surface.hpp", "thickness.hpp"]},  # plane measure, medial surface, thickness
    "tree": {"headers": []},  # the skeleton-tree
    "rig": {"headers": []},  # autorig (rig/autorig/), bind, rest matrices
    "skin": {"headers": []},  # skin weights
    "mesh": {"headers": []},  # mesh readers and writers, voxelize
    "deform": {"headers": []},
    "bvh": {"headers": []},  # motion capture files
    "centerline": {"headers": []},
    "collide": {"headers": []},
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



def problems() -> list[str]:
    out: list[str] = []
    rel = lambda p: p.relative_to(REPO).as_posix()  # noqa: E731

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


def main() -> int:
    found = problems()
    for p in found:
        print(p)
    print(f"check_layout: {len(CAPABILITIES)} capabilities, {len(found)} problem(s)")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
