"""A procedural volumetric humanoid with known anatomy, for tests and demos.

``humanoid(scale, spacing)`` builds a standing character on the Visible Male half-resolution grid (290 x 169 x 940
voxels at scale 1; each size times ``scale``, rounded half up, at other scales): z up, facing -y, its left side
(``.L``) on +x, arms hanging in a slight A-pose clear of the torso, feet apart. Voxels are uint8: background 0, skin
80 (the outer ~2 voxels * scale), flesh 100 and bone 220. At scale 1 about 22% of the grid is body.

The body is a union of tapered capsules (cone-spheres: the union of the spheres centred on a segment a -> b whose
radius goes linearly from ra to rb) for the neck, shoulders and limbs, and ellipsoids for the chest, abdomen, pelvis
and head. Bones are thinner capsules along each limb segment (0.4 of the limb radius), a spine column, a skull
shell, a rib cage of elliptic bands and a pelvis block, all strictly inside the flesh. Each primitive is evaluated
only inside its bounding box; the right side is the exact mirror image of the left. Deterministic.

Units: the anatomy is written in voxels of the scale-1 grid; ``Phantom.joints``, ``Phantom.segments`` and
``Phantom.ellipsoids`` are in world units (voxel index * spacing; origin 0).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, List, Tuple

import numpy as np

from ._volrig import VolrigError
from .volume import Volume

BACKGROUND, SKIN, FLESH, BONE = 0, 80, 100, 220

#: grid size (x, y, z) at scale 1: the Visible Male at half resolution.
BASE_DIMS = (290, 169, 940)

# ---- anatomy in scale-1 voxels: x across (body centre 144.5), y front (small) to back, z up (grid centre 469.5) ----

_CX = 144.5

#: centre-line joints (x = _CX)
_CENTRE_JOINTS = {
    "hips": (88.0, 478.0),
    "spine": (90.0, 568.0),
    "chest": (90.0, 660.0),
    "neck": (94.0, 762.0),
    "head": (90.0, 812.0),
    "head_top": (84.0, 903.0),
}

#: left-side joints (x, y, z); the right side mirrors x about _CX
_LEFT_JOINTS = {
    "shoulder": (236.0, 94.0, 748.0),
    "elbow": (256.0, 98.0, 586.0),
    "wrist": (258.0, 88.0, 458.0),
    "hand_tip": (259.0, 82.0, 374.0),
    "hip": (_CX + 44.0, 90.0, 470.0),
    "knee": (_CX + 50.0, 84.0, 272.0),
    "ankle": (_CX + 56.0, 98.0, 40.0),
    "toe": (_CX + 60.0, 28.0, 29.0),
}

#: flesh capsules: name, joint a, joint b, radius a, radius b (scale-1 voxels); ".L" ones are mirrored to ".R"
_CAPSULES = [
    ("neck", "neck", "head", 30.0, 28.0),
    ("clavicle.L", "neck", "shoulder.L", 31.0, 30.0),
    ("upper_arm.L", "shoulder.L", "elbow.L", 32.0, 26.0),
    ("forearm.L", "elbow.L", "wrist.L", 25.0, 16.0),
    ("hand.L", "wrist.L", "hand_tip.L", 15.0, 11.0),
    ("thigh.L", "hip.L", "knee.L", 44.0, 38.0),
    ("shin.L", "knee.L", "ankle.L", 37.0, 24.0),
    ("foot.L", "ankle.L", "toe.L", 27.0, 17.0),
]

#: flesh ellipsoids: name, centre (y, z) on the centre line, semi-axes (x, y, z) in scale-1 voxels
_ELLIPSOIDS = [
    ("chest", (90.0, 645.0), (70.0, 74.0, 118.0)),
    ("abdomen", (88.0, 560.0), (68.0, 70.0, 90.0)),
    ("pelvis", (92.0, 480.0), (84.0, 74.0, 76.0)),
    ("head", (84.0, 853.0), (43.0, 50.0, 60.0)),
]

#: limb bones run along the flesh capsules with this fraction of their radii
_BONE_FRACTION = 0.4
#: spine column polyline (y, z) and radii; the column runs behind the torso's centre
_SPINE = [((100.0, 470.0), 13.0), ((108.0, 568.0), 13.0), ((110.0, 660.0), 12.0), ((102.0, 762.0), 10.0),
          ((96.0, 812.0), 9.0)]
#: skull: the head ellipsoid shrunk by these (scalp, then bone thickness) in scale-1 voxels
_SCALP, _SKULL = 6.5, 6.5
#: rib cage: an elliptic shell (centre y, z; semi-axes; thickness) cut into bands of `period` with `on` of bone
_RIBS = dict(centre=(92.0, 655.0), radii=(64.0, 46.0, 92.0), thickness=5.0, z_range=(585.0, 735.0), period=15.0,
             on=6.0)
#: pelvis bone block: ellipsoid centre (y, z) and semi-axes
_PELVIS_BONE = ((92.0, 486.0), (56.0, 34.0, 34.0))
#: skin thickness in scale-1 voxels
_SKIN = 2.0


@dataclass(frozen=True)
class Segment:
    """A flesh capsule (cone-sphere) between two joints; radii in world units."""
    name: str
    joint_a: str
    joint_b: str
    radius_a: float
    radius_b: float


@dataclass(frozen=True)
class Ellipsoid:
    """A flesh ellipsoid (torso parts, head); centre and semi-axes (x, y, z) in world units."""
    name: str
    centre: Tuple[float, float, float]
    radii: Tuple[float, float, float]


@dataclass
class Phantom:
    """The humanoid: the volume, its joints and the flesh primitives it was built from.

    volume:     uint8 Volume [z, y, x]: 0 background, 80 skin, 100 flesh, 220 bone; spacing (s, s, s), origin 0.
    joints:     name -> world position (x, y, z) (numpy float64): hips, spine, chest, neck, head, head_top and
                shoulder, elbow, wrist, hand_tip, hip, knee, ankle, toe with .L (+x, the character's left) and .R.
    segments:   the flesh capsules (limbs, neck, clavicles), radii in world units.
    ellipsoids: the flesh ellipsoids (chest, abdomen, pelvis, head), in world units.
    """
    volume: Volume
    joints: Dict[str, np.ndarray]
    segments: List[Segment]
    ellipsoids: List[Ellipsoid] = field(default_factory=list)

    def segment(self, name: str) -> Segment:
        for s in self.segments:
            if s.name == name:
                return s
        raise KeyError(f"no segment named {name!r} (segments: {', '.join(s.name for s in self.segments)})")

    def segment_mask(self, name: str) -> np.ndarray:
        """Boolean voxel mask [z, y, x] of one flesh primitive: a capsule of ``segments`` (e.g. "upper_arm.L") or
        an ellipsoid of ``ellipsoids`` (e.g. "chest"). Skin included; other primitives not."""
        shape = self.volume.array.shape
        spacing = np.asarray(self.volume.spacing)
        out = np.zeros(shape, dtype=bool)
        for e in self.ellipsoids:
            if e.name == name:
                prim = _EllipsoidPrim(np.asarray(e.centre) / spacing, np.asarray(e.radii) / spacing)
                break
        else:
            s = self.segment(name)
            a = self.joints[s.joint_a] / spacing
            b = self.joints[s.joint_b] / spacing
            prim = _CapsulePrim(a, b, s.radius_a / spacing[0], s.radius_b / spacing[0])
        box = prim.box(shape)
        if box is not None:
            sl, sdf = prim.sdf(box)
            out[sl] = sdf < 0
        return out


# ---- primitives (voxel coordinates of the output grid) ---------------------------------------------------------

def _box_slices(lo, hi, shape):
    """Slices [z, y, x] covering voxel centres in [lo, hi] (x, y, z), clipped to the grid; None when empty."""
    nz, ny, nx = shape
    lo_i = np.maximum(np.floor(lo).astype(int), 0)
    hi_i = np.minimum(np.ceil(hi).astype(int), np.array([nx - 1, ny - 1, nz - 1]))
    if np.any(hi_i < lo_i):
        return None
    return (slice(lo_i[2], hi_i[2] + 1), slice(lo_i[1], hi_i[1] + 1), slice(lo_i[0], hi_i[0] + 1))


def _coords(box):
    """Broadcastable float64 voxel coordinates (x, y, z) of a box of slices [z, y, x]."""
    z = np.arange(box[0].start, box[0].stop, dtype=np.float64)[:, None, None]
    y = np.arange(box[1].start, box[1].stop, dtype=np.float64)[None, :, None]
    x = np.arange(box[2].start, box[2].stop, dtype=np.float64)[None, None, :]
    return x, y, z


class _CapsulePrim:
    """Cone-sphere from a (radius ra) to b (radius rb); exact signed distance (after Inigo Quilez's round cone)."""

    def __init__(self, a, b, ra: float, rb: float):
        self.a = np.asarray(a, dtype=np.float64)
        self.b = np.asarray(b, dtype=np.float64)
        self.ra, self.rb = float(ra), float(rb)

    def box(self, shape, pad: float = 1.0):
        lo = np.minimum(self.a - self.ra, self.b - self.rb) - pad
        hi = np.maximum(self.a + self.ra, self.b + self.rb) + pad
        return _box_slices(lo, hi, shape)

    def sdf(self, box):
        x, y, z = _coords(box)
        ba = self.b - self.a
        l2 = float(ba @ ba)
        rr = self.ra - self.rb
        a2 = l2 - rr * rr
        il2 = 1.0 / l2
        pax, pay, paz = x - self.a[0], y - self.a[1], z - self.a[2]
        t = pax * ba[0] + pay * ba[1] + paz * ba[2]          # dot(pa, ba)
        w = t - l2
        # |pa * l2 - ba * t|^2 = l2^2 |pa|^2 - l2 t^2  (pa.ba = t)
        x2 = l2 * l2 * (pax * pax + pay * pay + paz * paz) - l2 * t * t
        np.maximum(x2, 0.0, out=x2)
        y2 = t * t * l2
        z2 = w * w * l2
        k = np.sign(rr) * rr * rr * x2
        d_mid = (np.sqrt(x2 * a2 * il2) + t * rr) * il2 - self.ra
        d_b = np.sqrt(x2 + z2) * il2 - self.rb
        d_a = np.sqrt(x2 + y2) * il2 - self.ra
        d = np.where(np.sign(w) * a2 * z2 > k, d_b, np.where(np.sign(t) * a2 * y2 < k, d_a, d_mid))
        return box, d


class _EllipsoidPrim:
    """Ellipsoid with centre c and semi-axes r; signed distance to first order (f / |grad f|, f = q - 1)."""

    def __init__(self, c, r):
        self.c = np.asarray(c, dtype=np.float64)
        self.r = np.asarray(r, dtype=np.float64)

    def box(self, shape, pad: float = 1.0):
        return _box_slices(self.c - self.r - pad, self.c + self.r + pad, shape)

    def q(self, box):
        x, y, z = _coords(box)
        u, v, w = (x - self.c[0]) / self.r[0], (y - self.c[1]) / self.r[1], (z - self.c[2]) / self.r[2]
        return u, v, w, np.sqrt(u * u + v * v + w * w)

    def sdf(self, box):
        u, v, w, q = self.q(box)
        g = np.sqrt((u / self.r[0]) ** 2 + (v / self.r[1]) ** 2 + (w / self.r[2]) ** 2)
        qs = np.maximum(q, 1e-9)
        d = (q - 1.0) / np.maximum(g / qs, 1e-12)
        return box, d


# ---- building --------------------------------------------------------------------------------------------------

def _mirror(name: str) -> str:
    return name[:-2] + ".R" if name.endswith(".L") else name


def _place(scale: float, dims_xyz):
    """Map scale-1 voxel coordinates (x, y, z) to this grid's voxels, keeping the body centred."""
    c1 = (np.asarray(BASE_DIMS, dtype=np.float64) - 1) / 2
    c1[0] = _CX
    cs = (np.asarray(dims_xyz, dtype=np.float64) - 1) / 2

    def place(p):
        return cs + (np.asarray(p, dtype=np.float64) - c1) * scale
    return place


def _paint_flesh(vol: np.ndarray, prim, skin: float):
    box = prim.box(vol.shape)
    if box is None:
        return
    _, d = prim.sdf(box)
    label = np.where(d < -skin, FLESH, np.where(d < 0, SKIN, BACKGROUND)).astype(np.uint8)
    np.maximum(vol[box], label, out=vol[box])


def _paint_bone(vol: np.ndarray, box, inside: np.ndarray):
    region = vol[box]
    region[inside] = BONE


def humanoid(scale: float = 1.0, spacing: float = 1.0) -> Phantom:
    """Build the humanoid phantom.

    scale:   grid scale; 1.0 gives 290 x 169 x 940 voxels (x, y, z), 0.5 gives 145 x 85 x 470 (each size
             rounded half up). All anatomy scales with it (in voxels).
    spacing: world units per voxel (the same on all axes); joints and radii are reported in world units.
    Returns a Phantom; deterministic. About 2 s at scale 1 on one core.
    """
    scale = float(scale)
    spacing = float(spacing)
    if not (np.isfinite(scale) and scale > 0):
        raise VolrigError(f"scale must be positive, got {scale}")
    if not (np.isfinite(spacing) and spacing > 0):
        raise VolrigError(f"spacing must be positive, got {spacing}")
    dims = tuple(max(1, int(np.floor(d * scale + 0.5))) for d in BASE_DIMS)  # round half up: 169 * 0.5 -> 85
    nx, ny, nz = dims
    place = _place(scale, dims)
    centre_x = (nx - 1) / 2
    skin = _SKIN * scale

    # joints in this grid's voxels
    jv: Dict[str, np.ndarray] = {}
    for name, (y, z) in _CENTRE_JOINTS.items():
        jv[name] = place((_CX, y, z))
    for name, p in _LEFT_JOINTS.items():
        left = place(p)
        jv[name + ".L"] = left
        jv[name + ".R"] = np.array([2 * centre_x - left[0], left[1], left[2]])

    vol = np.zeros((nz, ny, nx), dtype=np.uint8)

    # flesh: the centre primitives and the left side; the right side is mirrored at the end
    ellipsoids = []
    for name, (y, z), r in _ELLIPSOIDS:
        c = place((_CX, y, z))
        rs = np.asarray(r) * scale
        _paint_flesh(vol, _EllipsoidPrim(c, rs), skin)
        ellipsoids.append(Ellipsoid(name, tuple(c * spacing), tuple(rs * spacing)))
    segments = []
    for name, ja, jb, ra, rb in _CAPSULES:
        cap = _CapsulePrim(jv[ja], jv[jb], ra * scale, rb * scale)
        _paint_flesh(vol, cap, skin)
        segments.append(Segment(name, ja, jb, ra * scale * spacing, rb * scale * spacing))
        if name.endswith(".L"):
            segments.append(Segment(_mirror(name), _mirror(ja), _mirror(jb), ra * scale * spacing,
                                    rb * scale * spacing))

    # bones
    for name, ja, jb, ra, rb in _CAPSULES:
        if name == "neck":
            continue  # the spine runs through the neck
        a, b = jv[ja], jv[jb]
        if name.startswith("clavicle"):
            a = a + 0.3 * (b - a)  # the clavicle starts beside the spine, not inside it
        cap = _CapsulePrim(a, b, ra * scale * _BONE_FRACTION, rb * scale * _BONE_FRACTION)
        box = cap.box(vol.shape)
        _, d = cap.sdf(box)
        _paint_bone(vol, box, d < 0)
    for (p0, r0), (p1, r1) in zip(_SPINE[:-1], _SPINE[1:]):
        cap = _CapsulePrim(place((_CX,) + p0), place((_CX,) + p1), r0 * scale, r1 * scale)
        box = cap.box(vol.shape)
        _, d = cap.sdf(box)
        _paint_bone(vol, box, d < 0)
    # skull: a shell inside the head ellipsoid
    (hy, hz), hr = [(c, r) for n, c, r in _ELLIPSOIDS if n == "head"][0]
    outer = _EllipsoidPrim(place((_CX, hy, hz)), (np.asarray(hr) - _SCALP) * scale)
    inner = _EllipsoidPrim(place((_CX, hy, hz)), (np.asarray(hr) - _SCALP - _SKULL) * scale)
    box = outer.box(vol.shape)
    _, d_out = outer.sdf(box)
    _, d_in = inner.sdf(box)
    _paint_bone(vol, box, (d_out < 0) & (d_in >= 0))
    # rib cage: elliptic bands
    rib = _EllipsoidPrim(place((_CX,) + _RIBS["centre"]), np.asarray(_RIBS["radii"]) * scale)
    box = rib.box(vol.shape)
    _, d = rib.sdf(box)
    z = np.arange(box[0].start, box[0].stop, dtype=np.float64)[:, None, None]
    z1 = (z - place((0, 0, 0))[2]) / scale  # back to scale-1 z
    lo, hi = _RIBS["z_range"]
    bands = (z1 >= lo) & (z1 <= hi) & (np.mod(z1 - lo, _RIBS["period"]) < _RIBS["on"])
    _paint_bone(vol, box, (d < 0) & (d >= -_RIBS["thickness"] * scale) & bands)
    # pelvis block
    (py, pz), pr = _PELVIS_BONE
    pel = _EllipsoidPrim(place((_CX, py, pz)), np.asarray(pr) * scale)
    box = pel.box(vol.shape)
    _, d = pel.sdf(box)
    _paint_bone(vol, box, d < 0)

    # exact left/right symmetry: the right side is the mirror image of the left
    np.maximum(vol, vol[:, :, ::-1], out=vol)

    joints = {name: p * spacing for name, p in jv.items()}
    return Phantom(Volume(vol, (spacing,) * 3, (0.0, 0.0, 0.0)), joints, segments, ellipsoids)
