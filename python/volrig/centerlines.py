"""The old name of ``volrig.centerline`` (renamed in issue 52: one capability, one name at every layer).

Kept so that existing code (``from volrig.centerlines import straighten``, ``volrig.centerlines.flight_path``)
keeps working: importing it gives the ``volrig.centerline`` module itself. New code imports ``volrig.centerline``.
"""
import importlib
import sys

# Not `from . import centerline`: the package binds that name to the function volrig.centerline.
sys.modules[__name__] = importlib.import_module(".centerline", __package__)
