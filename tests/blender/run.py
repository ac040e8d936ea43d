"""Runs the add-on's tests inside Blender:

    blender -b --factory-startup --python-exit-code 1 --python tests/blender/run.py -- [pytest arguments]

Puts the repository's python/, addon/ and tests/support/ (volrig_support) folders on sys.path (pytest comes from
Debian's python3-pytest, which Blender's Python sees in /usr/lib/python3/dist-packages) and exits with pytest's
status."""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
for folder in (os.path.join(REPO, "python"), os.path.join(REPO, "addon"), os.path.join(REPO, "tests", "support")):
    if folder not in sys.path:
        sys.path.insert(0, folder)

import pytest  # noqa: E402

args = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
code = pytest.main(["-p", "no:cacheprovider", "--rootdir", REPO, HERE] + args)
sys.stdout.flush()
os._exit(int(code))  # Blender would otherwise carry on and exit 0
