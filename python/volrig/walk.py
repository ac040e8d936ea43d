"""A procedural walk cycle for humanoid rigs (Rigify role names, as ``autorig`` gives them): joint angles per
frame, for demos and tests. Every swing is about the rig's left-right axis (from thigh.R to thigh.L), so the
angles compose down each limb whatever the rest pose; positive angles bend a downward limb backwards."""
from __future__ import annotations

from typing import Dict, Tuple

import numpy as np

from ._volrig import VolrigError
from .rig import Rig

#: bone -> (mean angle, amplitude, phase in cycles), degrees; phase 0.5 is the opposite side's swing.
_WALK = {
    "thigh.L": (-5.0, 28.0, 0.0), "thigh.R": (-5.0, 28.0, 0.5),
    "shin.L": (25.0, 25.0, 0.75), "shin.R": (25.0, 25.0, 0.25),
    "foot.L": (0.0, 12.0, 0.1), "foot.R": (0.0, 12.0, 0.6),
    "upper_arm.L": (0.0, 22.0, 0.5), "upper_arm.R": (0.0, 22.0, 0.0),
    "forearm.L": (-15.0, 12.0, 0.5), "forearm.R": (-15.0, 12.0, 0.0),
    "spine": (3.0, 2.0, 0.0), "neck": (-3.0, 2.0, 0.5),
}


def walk_cycle(rig: Rig, frames: int, period: float = 24.0, amplitude: float = 1.0) \
        -> Tuple[np.ndarray, Dict[str, np.ndarray]]:
    """The walk's swing axis (3,) in the rig's coordinates and, for each bone of the walk the rig has, its angle
    in radians at frames 0 .. frames-1 (one stride every ``period`` frames, angles scaled by ``amplitude``).
    Raises ValueError when the rig has no thigh.L/thigh.R (not a humanoid)."""
    try:
        left, right = rig.heads()[rig.index("thigh.L")], rig.heads()[rig.index("thigh.R")]
    except KeyError:
        raise VolrigError(f"a walk needs a humanoid rig with thigh.L and thigh.R (this one is {rig.kind}: "
                         f"{', '.join(rig.names[:6])}...)") from None
    axis = left - right
    if not np.linalg.norm(axis) > 0:
        raise VolrigError("thigh.L and thigh.R start at the same point")
    if frames < 1 or not period > 0:
        raise VolrigError(f"need frames >= 1 and period > 0, got {frames}, {period}")
    t = np.arange(frames) / float(period)
    angles = {name: np.radians(amplitude * (mean + amp * np.sin(2 * np.pi * (t - phase))))
              for name, (mean, amp, phase) in _WALK.items() if name in rig.names}
    return axis / np.linalg.norm(axis), angles


def walk_matrices(rig: Rig, frames: int, period: float = 24.0, amplitude: float = 1.0) -> np.ndarray:
    """(frames, B, 4, 4) rest-to-pose matrices of ``walk_cycle``'s angles (``Rig.pose`` per frame)."""
    axis, angles = walk_cycle(rig, frames, period, amplitude)
    return np.array([rig.pose({n: (axis, np.degrees(a[f])) for n, a in angles.items()}) for f in range(frames)])
