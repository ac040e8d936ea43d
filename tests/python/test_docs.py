"""The documentation stays true to the repository: the README is a front door (at most 300 lines), every relative
link and picture in the README, docs/*.md and benchmarks/RESULTS.md resolves to a file, and every repository path
docs/ARCHITECTURE.md and docs/DESIGN.md name in backticks exists. Plain file reads: no volrig import."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
README_MAX_LINES = 300

LINKED_PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), ROOT / "benchmarks" / "RESULTS.md"]
PATH_PAGES = [ROOT / "docs" / "ARCHITECTURE.md", ROOT / "docs" / "DESIGN.md"]

# the top-level folders (and files) whose paths a page may name in backticks
TOP = ("native/", "python/", "addon/", "scripts/", "tests/", "benchmarks/", "farm/", "docs/", "blend_samples/",
       "CMakeLists.txt", "LICENSE", ".ci/")
FENCE = re.compile(r"^```.*?^```", re.S | re.M)
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
CODE = re.compile(r"`([^`\n]+)`")


def _rel(page):
    return page.relative_to(ROOT).as_posix()


def relative_links(text):
    """Targets of the page's Markdown links and pictures that point into the repository (no URL, no bare #anchor),
    without their #anchor; code blocks are left out."""
    targets = []
    for target in LINK.findall(FENCE.sub("", text)):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
            continue
        targets.append(target.split("#", 1)[0])
    return targets


SOURCE_DIRS = ("native", "python", "addon", "scripts", "benchmarks", "tests", "farm")
SOURCE_FILE = re.compile(r"^[\w.-]+\.(py|cpp|hpp|js)$")


def repository_paths(text):
    """Repository paths written in backticks, outside code blocks: the first word of each code span that is a path
    from the top level (`native/src/io.cpp`, `python/volrig/pipeline.py`), from the core's folders (`src/bind.cpp`,
    `src/deform/`, `volrig/deform.hpp`: native/src, native/include) or a bare source file name (`gather.cpp`,
    `mesh_rig.py`; `motion.hpp/.cpp` is both). Globs (`*`), placeholders (`<name>`) and brace lists are skipped.
    Returns (as written, candidate paths: the name exists when one of them does)."""
    found = []
    for span in CODE.findall(FENCE.sub("", text)):
        words = span.split()
        word = words[0].rstrip(",;:.)") if words else ""
        if not word or any(c in word for c in "*<>{}$?[("):
            continue
        if word.startswith(TOP):
            found.append((word, [word]))
        elif word.startswith("src/") or word.startswith("include/volrig/"):
            found.append((word, ["native/" + word]))
        elif word.startswith("volrig/") and "/" not in word[len("volrig/"):]:
            found.append((word, ["native/include/" + word, "python/" + word]))
        else:
            names = [word]
            if word.endswith("/.cpp"):  # motion.hpp/.cpp
                stem = word[:-len("/.cpp")].rsplit(".", 1)[0]
                names = [stem + ".hpp", stem + ".cpp"]
            if all(SOURCE_FILE.match(n) for n in names):
                found.extend((n, ["**/" + n]) for n in names)
    return found


def _exists(candidate):
    if candidate.startswith("**/"):
        name = candidate[3:]
        return any(next((ROOT / d).rglob(name), None) is not None for d in SOURCE_DIRS)
    return (ROOT / candidate).exists()


def test_readme_is_short():
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= README_MAX_LINES, (
        f"README.md has {len(lines)} lines (at most {README_MAX_LINES}): move detail to a page under docs/")


@pytest.mark.parametrize("page", LINKED_PAGES, ids=_rel)
def test_relative_links_resolve(page):
    assert page.is_file(), f"{_rel(page)} is missing"
    missing = [t for t in relative_links(page.read_text(encoding="utf-8"))
               if not (page.parent / t).resolve().exists()]
    assert not missing, f"{_rel(page)} links to files that do not exist: {missing}"


@pytest.mark.parametrize("page", PATH_PAGES, ids=_rel)
def test_named_paths_exist(page):
    missing = sorted({written for written, candidates in repository_paths(page.read_text(encoding="utf-8"))
                      if not any(_exists(c) for c in candidates)})
    assert not missing, (f"{_rel(page)} names paths that do not exist (moved or renamed? update the page): "
                         f"{missing}")


def test_architecture_names_paths():
    # guards the pattern above: a page that seems to name no path would pass whatever it says
    paths = repository_paths((ROOT / "docs" / "ARCHITECTURE.md").read_text(encoding="utf-8"))
    assert len(paths) > 50, f"only {len(paths)} paths found in docs/ARCHITECTURE.md: is the pattern still right?"


def test_readme_names_the_test_command():
    # .ci/run runs scripts/test, "exactly the README's test command"
    assert "scripts/test" in (ROOT / "README.md").read_text(encoding="utf-8")
