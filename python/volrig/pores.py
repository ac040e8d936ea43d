"""Pore networks of rock (thesis 9.4, "oil discovery"): pores, throats and their flow, from a pore mask.

``pore_network(pore_mask, voxel=...)`` extracts the network of the pore space in the native core (docs/pores.md):
the pore space's Euclidean distance transform (image faces open) gives the maximal inscribed balls; pores are seeded
at its local maxima (the skeleton's largest balls), largest first, a seed dropped when a kept pore's ball contains
its centre; a watershed of the distance transform assigns every pore voxel to one pore; throats join pores whose
regions share a voxel face, with an inscribed diameter of twice the largest distance on that interface.

Flow: absolute permeability and formation factor along x, y and z from a sparse linear solve in the native core,
as OpenPNM's StokesFlow and FickianDiffusion do on a SNOW network (OpenPNM's Berea example): conduits of pore 1's
half, the throat and pore 2's half, pores as truncated pyramids of their volume-equivalent diameter, throats as
cuboids of their inscribed diameter (Hagen-Poiseuille conductances of a square section for flow, the sections for
diffusion), unit pressure between opposite faces, each face's pores joined to it by their half conduit.

Axis order: arrays of the image are [z, y, x]; every coordinate of the network is world x, y, z in metres (or in
the voxel's unit), from the image's corner (voxel (i, j, k) spans [i, i + 1) * voxel), as OpenPNM keeps them.
numpy and the native core only (no scipy).
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, Optional, Sequence, Union

import numpy as np

from . import _volrig
from ._volrig import VolrigError
from .skeleton import ProgressFn
from .volume import Volume

FACES = ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")  # bit k of the native face flags is FACES[k]
AXES = "xyz"
MODELS = ("pyramids_and_cuboids", "cones_and_cylinders")
MILLIDARCY = 9.869233e-16  # m² per mD


@dataclass
class PoreNetwork:
    """A pore network (world x, y, z coordinates; lengths in the voxel's unit, metres for a voxel in metres).

    porosity:                  pore voxels / all voxels (exact).
    pore_coords:               (N, 3) centres of mass of the pores' regions.
    pore_diameter:             (N,) inscribed diameters (2 x the largest distance in the region).
    pore_equivalent_diameter:  (N,) diameters of the sphere of the region's volume.
    pore_volume:               (N,) region volumes (every pore voxel in one region).
    pore_faces:                {"xmin": (N,) bool, ...}: pores whose region touches each face of the image.
    throat_conns:              (M, 2) int pore indices, the smaller first.
    throat_diameter:           (M,) inscribed diameters (2 x the largest distance on the two regions' interface).
    throat_total_length:       (M,) |pore 1 - throat| + |throat - pore 2|, through the throat's widest point.
    throat_coords:             (M, 3) that point. throat_area: (M,) the interface's area.
    permeability:              (3,) absolute permeability along x, y, z (m² for a voxel in metres); 0 where no
                               path joins the two faces.
    formation_factor:          (3,) D_bulk / D_eff along x, y, z; inf where no path joins the two faces.
    shape:                     the image's shape [z, y, x]; voxel: its spacing (x, y, z).
    regions:                   with ``pore_network(..., regions=True)``: int32 [z, y, x], each voxel its pore's
                               index + 1 (0 = solid); else None.
    """
    porosity: float
    pore_coords: np.ndarray
    pore_diameter: np.ndarray
    pore_equivalent_diameter: np.ndarray
    pore_volume: np.ndarray
    pore_faces: Dict[str, np.ndarray]
    throat_conns: np.ndarray
    throat_diameter: np.ndarray
    throat_total_length: np.ndarray
    throat_coords: np.ndarray
    throat_area: np.ndarray
    shape: tuple
    voxel: tuple
    model: str = "pyramids_and_cuboids"
    permeability: np.ndarray = field(default_factory=lambda: np.zeros(3))
    formation_factor: np.ndarray = field(default_factory=lambda: np.full(3, np.inf))
    regions: Optional[np.ndarray] = None

    @property
    def pore_count(self) -> int:
        return len(self.pore_volume)

    @property
    def throat_count(self) -> int:
        return len(self.throat_diameter)

    @property
    def coordination(self) -> np.ndarray:
        """Per pore, the number of its throats."""
        return np.bincount(self.throat_conns.ravel(), minlength=self.pore_count)

    @property
    def permeability_md(self) -> np.ndarray:
        """Permeability along x, y, z in millidarcy (for a voxel in metres)."""
        return self.permeability / MILLIDARCY

    def to_openpnm(self) -> Dict[str, np.ndarray]:
        """OpenPNM's dictionary layout (``op.io.network_from_porespy`` takes it)."""
        d = {"pore.coords": self.pore_coords, "pore.inscribed_diameter": self.pore_diameter,
             "pore.equivalent_diameter": self.pore_equivalent_diameter, "pore.volume": self.pore_volume,
             "throat.conns": self.throat_conns, "throat.inscribed_diameter": self.throat_diameter,
             "throat.total_length": self.throat_total_length, "throat.global_peak": self.throat_coords,
             "throat.cross_sectional_area": self.throat_area}
        d.update({f"pore.{f}": self.pore_faces[f] for f in FACES})
        return d

    def save(self, path: Union[str, Path]) -> list:
        """Writes ``.npz`` (OpenPNM's keys, plus ``volrig.*`` keys of the image and the flow: drop them before
        handing the dict to OpenPNM) or, for a ``.csv`` path, ``<stem>_pores.csv`` and ``<stem>_throats.csv``.
        Returns the paths written."""
        path = Path(path)
        if path.suffix.lower() == ".csv":
            return self.save_csv(path.with_name(path.stem + "_pores.csv"), path.with_name(path.stem + "_throats.csv"))
        if path.suffix.lower() != ".npz":
            raise VolrigError(f"pore network: write .npz or .csv, not {path.name}")
        meta = {"volrig.porosity": np.float64(self.porosity), "volrig.shape": np.asarray(self.shape),
                "volrig.voxel": np.asarray(self.voxel, float), "volrig.permeability": self.permeability,
                "volrig.formation_factor": self.formation_factor, "volrig.model": np.asarray(self.model)}
        with open(path, "wb") as f:
            np.savez(f, **self.to_openpnm(), **meta)
        return [path]

    def save_csv(self, pores_path: Union[str, Path], throats_path: Union[str, Path]) -> list:
        """One row a pore (index, x, y, z, diameters, volume, faces) and one a throat (index, pores, diameter,
        lengths, area)."""
        with open(pores_path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["pore", "x", "y", "z", "inscribed_diameter", "equivalent_diameter", "volume", *FACES])
            for i in range(self.pore_count):
                w.writerow([i, *map(repr, self.pore_coords[i].tolist()), repr(float(self.pore_diameter[i])),
                            repr(float(self.pore_equivalent_diameter[i])), repr(float(self.pore_volume[i])),
                            *(int(self.pore_faces[k][i]) for k in FACES)])
        with open(throats_path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["throat", "pore1", "pore2", "inscribed_diameter", "total_length", "cross_sectional_area"])
            for t in range(self.throat_count):
                w.writerow([t, int(self.throat_conns[t, 0]), int(self.throat_conns[t, 1]),
                            repr(float(self.throat_diameter[t])), repr(float(self.throat_total_length[t])),
                            repr(float(self.throat_area[t]))])
        return [Path(pores_path), Path(throats_path)]


def load_network(path: Union[str, Path]) -> PoreNetwork:
    """Reads a network ``PoreNetwork.save`` wrote as ``.npz``."""
    with np.load(path) as z:
        d = {k: z[k] for k in z.files}
    try:
        return PoreNetwork(
            porosity=float(d["volrig.porosity"]), pore_coords=d["pore.coords"],
            pore_diameter=d["pore.inscribed_diameter"],
            pore_equivalent_diameter=d["pore.equivalent_diameter"], pore_volume=d["pore.volume"],
            pore_faces={f: d[f"pore.{f}"] for f in FACES}, throat_conns=d["throat.conns"],
            throat_diameter=d["throat.inscribed_diameter"], throat_total_length=d["throat.total_length"],
            throat_coords=d["throat.global_peak"], throat_area=d["throat.cross_sectional_area"],
            shape=tuple(int(s) for s in d["volrig.shape"]), voxel=tuple(float(v) for v in d["volrig.voxel"]),
            model=str(d["volrig.model"]), permeability=d["volrig.permeability"],
            formation_factor=d["volrig.formation_factor"])
    except KeyError as e:
        raise VolrigError(f"{path}: not a volrig pore network ({e.args[0]} missing)") from None


def _mask(pore_mask) -> np.ndarray:
    arr = pore_mask.array if isinstance(pore_mask, Volume) else np.asarray(pore_mask)
    if arr.ndim != 3:
        raise VolrigError(f"pore_network: the pore mask must be 3-D [z, y, x], got shape {arr.shape}")
    if arr.dtype.kind == "f" and not np.isfinite(arr).all():
        raise VolrigError("pore_network: the pore mask holds NaN or infinite values")
    if arr.dtype != np.bool_ and arr.dtype != np.uint8:
        arr = arr != 0
    return np.ascontiguousarray(arr).view(np.uint8)


def _voxel(pore_mask, voxel) -> tuple:
    if voxel is None:
        voxel = pore_mask.spacing if isinstance(pore_mask, Volume) else 1.0
    v = tuple(float(x) for x in np.broadcast_to(np.asarray(voxel, float), (3,)))
    if not all(np.isfinite(x) and x > 0 for x in v):
        raise VolrigError(f"pore_network: the voxel size must be positive and finite, got {voxel}")
    return v


def pore_network(pore_mask, voxel: Union[float, Sequence[float], None] = None, model: str = "pyramids_and_cuboids",
                 regions: bool = False, progress: ProgressFn = None) -> PoreNetwork:
    """The pore network of a pore mask, with its permeability and formation factor along x, y and z.

    pore_mask: a 3-D array [z, y, x] or a ``Volume``; non-zero / True = pore.
    voxel:     the voxel's size (one number, or x, y, z), metres for permeability in m²; default the Volume's
               spacing, else 1.
    model:     the conduits' shapes: "pyramids_and_cuboids" (OpenPNM's SNOW Berea example) or
               "cones_and_cylinders" (round sections: Hagen-Poiseuille's pi r^4 / 8 L).
    regions:   keep the pores' regions (``PoreNetwork.regions``, 4 bytes a voxel).
    progress:  optional callable(fraction) -> bool; False cancels (``volrig.Cancelled``).
    Raises ``VolrigError`` for a mask without pore or without solid voxels, or with NaN values.
    """
    if model not in MODELS:
        raise VolrigError(f"pore_network: model must be one of {', '.join(MODELS)}, got {model!r}")
    arr = _mask(pore_mask)
    v = _voxel(pore_mask, voxel)
    raw = _volrig.pore_network(arr, v, (0.0, 0.0, 0.0), regions, progress)
    faces = raw["pore_faces"]
    net = PoreNetwork(
        porosity=float(raw["pore_voxels"]) / float(arr.size), pore_coords=raw["pore_coords"],
        pore_diameter=raw["pore_inscribed_diameter"], pore_volume=raw["pore_volume"],
        pore_equivalent_diameter=np.cbrt(6.0 * raw["pore_volume"] / np.pi),
        pore_faces={f: (faces & (1 << k)) != 0 for k, f in enumerate(FACES)},
        throat_conns=raw["throat_conns"].astype(np.int64), throat_diameter=raw["throat_inscribed_diameter"],
        throat_total_length=raw["throat_total_length"], throat_coords=raw["throat_coords"],
        throat_area=raw["throat_area"], shape=tuple(int(s) for s in arr.shape), voxel=v, model=model,
        regions=raw.get("regions"))
    net.permeability, net.formation_factor = transport(net)
    return net


def _conduit_lengths(d1, d2, spacing):
    """Pore 1's, the throat's and pore 2's lengths of each conduit: half a pore each (shared in proportion where the
    pores overlap), the throat the rest (OpenPNM's cones_and_cylinders / pyramids_and_cuboids lengths)."""
    l1, l2 = d1 / 2.0, d2 / 2.0
    over = spacing < (d1 + d2) / 2.0
    s = np.maximum(spacing, 1e-300)
    l1 = np.where(over, (4 * s ** 2 + d1 ** 2 - d2 ** 2) / (8 * s), l1)
    l1 = np.clip(l1, 1e-3 * s, s)
    l2 = np.where(over, s - l1, l2)
    l2 = np.maximum(l2, 1e-3 * s)
    lt = np.maximum(spacing - l1 - l2, 1e-3 * s)
    return l1, lt, l2


def _pore_part(d, dt, length, model):
    """Hydraulic and diffusive size factors of a pore's part of a conduit: a truncated pyramid (cone) from the pore's
    diameter d to the throat's dt over `length`."""
    if model == "pyramids_and_cuboids":
        f = length * (d ** 2 + d * dt + dt ** 2) / (3.0 * d ** 3 * dt ** 3)   # integral of 1 / A² along it
        return 6.0 / (16.0 * np.pi ** 2 * f), d * dt / length
    f = 16.0 / 3.0 * length * (d ** 2 + d * dt + dt ** 2) / (d ** 3 * dt ** 3 * np.pi ** 2)
    return 2.0 * np.pi / (16.0 * np.pi ** 2 * f), np.pi * d * dt / (4.0 * length)


def _throat_part(dt, length, model):
    """Hydraulic and diffusive size factors of a throat: a cuboid (cylinder) of diameter dt."""
    if model == "pyramids_and_cuboids":
        return 6.0 * dt ** 4 / (16.0 * np.pi ** 2 * length), dt ** 2 / length
    return np.pi * dt ** 4 / (128.0 * length), np.pi * dt ** 2 / (4.0 * length)


def _series(*parts):
    return 1.0 / sum(1.0 / p for p in parts)


def conductances(net: PoreNetwork):
    """Per throat, the hydraulic (viscosity 1) and diffusive (diffusivity 1) conductances of its conduit."""
    d = net.pore_equivalent_diameter
    p1, p2 = net.throat_conns[:, 0], net.throat_conns[:, 1]
    dt = np.maximum(net.throat_diameter, 1e-12 * min(net.voxel))
    l1, lt, l2 = _conduit_lengths(d[p1], d[p2], net.throat_total_length)
    h1, f1 = _pore_part(d[p1], dt, l1, net.model)
    h2, f2 = _pore_part(d[p2], dt, l2, net.model)
    ht, ft = _throat_part(dt, lt, net.model)
    return _series(h1, ht, h2), _series(f1, ft, f2)


def _face_conduits(net: PoreNetwork, axis: int, side: int):
    """The pores on one face and the conductances joining each to the face: its half conduit (a prism of its
    diameter) from its centre to the face's plane."""
    pores = np.flatnonzero(net.pore_faces[FACES[2 * axis + side]])
    extent = net.shape[2 - axis] * net.voxel[axis]
    c = net.pore_coords[pores, axis]
    length = np.maximum(c if side == 0 else extent - c, 0.5 * net.voxel[axis])
    d = net.pore_equivalent_diameter[pores]
    h, f = _throat_part(d, length, net.model)
    return pores, h, f


def transport(net: PoreNetwork):
    """Permeability (m² for a voxel in metres) and formation factor along x, y and z: unit pressure (concentration)
    between the two faces of an axis, each face a node joined to its pores; K = Q mu L / (A dP), F = 1 / D_eff with
    D_eff = N L / (A dC)."""
    gh, gd = conductances(net) if net.throat_count else (np.zeros(0), np.zeros(0))
    perm, form = np.zeros(3), np.full(3, np.inf)
    n = net.pore_count
    for axis in range(3):
        lo, hlo, dlo = _face_conduits(net, axis, 0)
        hi, hhi, dhi = _face_conduits(net, axis, 1)
        if len(lo) == 0 or len(hi) == 0:
            continue
        conns = np.concatenate([net.throat_conns, np.stack([lo, np.full(len(lo), n)], 1),
                                np.stack([hi, np.full(len(hi), n + 1)], 1)]).astype(np.int32)
        inlet = np.zeros(n + 2, np.uint8)
        outlet = np.zeros(n + 2, np.uint8)
        inlet[n], outlet[n + 1] = 1, 1
        q = _volrig.network_rate(n + 2, conns, np.concatenate([gh, hlo, hhi]), inlet, outlet)
        rate = _volrig.network_rate(n + 2, conns, np.concatenate([gd, dlo, dhi]), inlet, outlet)
        length = net.shape[2 - axis] * net.voxel[axis]
        area = np.prod([net.shape[2 - a] * net.voxel[a] for a in range(3) if a != axis])
        perm[axis] = q * length / area
        form[axis] = area / (rate * length) if rate > 0 else np.inf
    return perm, form
