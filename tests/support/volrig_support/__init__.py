"""volrig's test support (not part of the volrig package): the shared test subjects (``subjects``), the procedural
test drawings (``sketches``) and ``data_root``, where the shared data live.

tests/python/conftest.py, tests/blender/run.py and the benchmarks and scripts that need it put tests/support on
sys.path; ``import volrig`` never imports it.
"""
import os
from pathlib import Path

#: the repository this folder belongs to (tests/support/volrig_support -> the checkout)
REPO = Path(__file__).resolve().parents[3]
#: tests/support, the folder to put on sys.path to import volrig_support
SUPPORT = Path(__file__).resolve().parents[1]


def data_root() -> Path:
    """Where the shared data live: $VOLRIG_DATA when set, else ../shared/data beside the repository."""
    env = os.environ.get("VOLRIG_DATA")
    if env:
        return Path(env)
    return (REPO / ".." / "shared" / "data").resolve()
