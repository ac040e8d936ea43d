"""Project files: pyproject.toml's metadata agrees with the package and the wheel's METADATA (scripts/extension),
and the Python that scripts/lint checks passes pyflakes."""
import subprocess
import tomllib

import pytest

import volrig
from conftest import REPO


def test_pyproject_metadata_matches_the_package():
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    assert project["name"] == "volrig"
    assert project["version"] == volrig.__version__
    assert project["license"] == volrig.__license__
    assert project["scripts"] == {"volrig": "volrig.cli:main"}
    assert project["dependencies"] == ["numpy"] and project["optional-dependencies"] == {"scipy": ["scipy"]}
    extension = (REPO / "scripts" / "extension").read_text()
    assert "volrig = volrig.cli:main" in extension and "License: GPL-3.0-or-later" in extension
    assert "Requires-Dist: numpy" in extension and 'Requires-Dist: scipy; extra == \\"scipy\\"' in extension


def test_pyflakes():
    pytest.importorskip("pyflakes", reason="pyflakes not installed (Debian: python3-pyflakes)")
    r = subprocess.run([str(REPO / "scripts" / "lint")], capture_output=True, text=True,
                       env={"PATH": "/usr/bin:/bin"})
    assert r.returncode == 0, r.stdout + r.stderr
