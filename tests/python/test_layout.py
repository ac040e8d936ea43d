"""The layout of the native code and the Python package: one capability, one name at every layer (tests/check_layout.py)."""
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_layout():
    r = subprocess.run([sys.executable, str(REPO / "tests" / "check_layout.py")], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
