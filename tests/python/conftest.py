"""Shared fixtures: where the real data lives, and skipping cleanly when it does not."""
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
if str(REPO / "tests" / "support") not in sys.path:
    sys.path.insert(0, str(REPO / "tests" / "support"))  # volrig_support: the test subjects, sketches, data_root

from volrig_support import data_root  # noqa: E402

SHARED_DATA = data_root()


def shared(relative: str) -> Path:
    """Path of a file under ../shared/data; skips the test with a clear reason when it is absent."""
    p = SHARED_DATA / relative
    if not p.exists():
        pytest.skip(f"real data not available: {p} (the ../shared/data folder sits beside the checkout)")
    return p


@pytest.fixture(scope="session")
def phantom_half():
    """The humanoid phantom at scale 0.5 (145 x 85 x 470), built once per session."""
    from volrig import phantom
    return phantom.humanoid(scale=0.5)
