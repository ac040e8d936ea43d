"""Per-tissue looks for label maps (issues 21, 56): tissue codes grouped into classes (skin, fat, muscle, bone, organs,
...), each with its own colour, opacity and visibility, written as ONE label grid ``tissue`` (each voxel's class
index, 1..K in the order of the classes; 0 = none) with the classes named in the file's metadata
(``METADATA``: key, name, colour, opacity, visible, codes), so a renderer shows each class its own way from one grid.

A label map's codes are not values: a renderer that interpolates them makes codes that are in neither tissue at every
boundary (fat 136 next to muscle 180 passes through 152, gland). The class index interpolates too (between classes 2
and 5 it passes 3 and 4), so the add-on's looks weigh each class by its index indicator times a match of the
interpolated codes with the class's own (``materials.tissue_sums``; docs/tissues.md, Why one grid renders right).
Skin is class 1 (``OUTER``: the body's surface fades as an occupancy would), the others follow by opacity
(``index_order``).

The classes come from a label table (code -> tissue name: ``read_tissue_table`` reads TSV or CSV files such as the
Visible Human's ``austinman_tissues.tsv``) matched against ``TISSUE_CLASSES``, a preset the user can edit or replace:
each code goes to the first class whose pattern matches its name; codes no class matches go to "other"; code 0 and
names matching ``OUTSIDE_NAMES`` (external air) are left out.
"""
from __future__ import annotations

import csv
import json
import os
import re
from typing import Dict, List, NamedTuple, Sequence, Tuple

import numpy as np

from ._volrig import VolrigError
from .volume import Volume


class TissueClass(NamedTuple):
    """A preset entry: ``pattern`` (a case-insensitive regular expression) matched against tissue names."""
    name: str
    pattern: str
    color: Tuple[float, float, float]
    opacity: float
    visible: bool = True


#: The preset: skin translucent over muscle red, fat yellow and faint, bone white, organs in their colours, gas
#: hidden. Opacity is relative (the renderer scales it). First match wins, so specific names come before general
#: ones ("BoneMarrow" is bone, not marrow fat; "HeartMuscle" and "HeartDCT" are heart; "InternalAir" is air).
TISSUE_CLASSES: List[TissueClass] = [
    TissueClass("skin", r"skin|nail", (0.95, 0.78, 0.66), 0.06),
    TissueClass("bone", r"bone|skeleton|tooth|teeth|skull|vertebra|rib|femur|tibia|humerus", (0.97, 0.94, 0.86), 1.0),
    TissueClass("heart", r"heart|ventricle|atri|myocard", (0.80, 0.10, 0.12), 0.8),
    TissueClass("cartilage", r"cartilage|menisc|disc|tendon|ligament|fascia|itband|dct", (0.80, 0.85, 0.92), 0.1),
    TissueClass("vessels", r"aorta|vessel|vein|artery|blood|vena", (0.70, 0.04, 0.06), 0.8),
    TissueClass("brain", r"brain|cerebell|pons|medulla|midbrain|spinalcord|spinal_cord|dura|csf|cerebrospinal",
                (0.92, 0.80, 0.76), 0.6),
    TissueClass("nerve", r"nerve", (0.98, 0.92, 0.40), 0.8),
    TissueClass("lung", r"lung|trachea|bronch", (0.92, 0.62, 0.68), 0.05),
    TissueClass("liver", r"liver|gall", (0.50, 0.13, 0.10), 0.6),
    TissueClass("kidney", r"kidney|renal|adrenal|bladder|urethra|prostate|testis|ductus|erectile",
                (0.65, 0.25, 0.38), 0.6),
    TissueClass("gut", r"colon|intestine|duoden|ileum|jejun|c[a]?ecum|stomach|esophag|bowel|rectum|peritoneal|mucous",
                (0.88, 0.58, 0.48), 0.3),
    TissueClass("glands", r"gland|pancrea|spleen|thymus|thyroid|lymph|tongue", (0.72, 0.35, 0.48), 0.5),
    TissueClass("eye", r"eye|cornea|lens|vitreous|sclera", (0.95, 0.95, 1.00), 0.6),
    TissueClass("muscle", r"muscle|diaphragm", (0.72, 0.16, 0.12), 0.1),
    TissueClass("fat", r"fat|adipose|marrow", (0.96, 0.86, 0.48), 0.006),
    TissueClass("air", r"air|gas", (1.0, 1.0, 1.0), 0.0, False),
]
#: Tissue names left out of every class (the air around the body; code 0 always is).
OUTSIDE_NAMES = r"^external.?air$|^air$|^background$|^outside$"
#: Codes in no class of the preset.
OTHER = TissueClass("other", r"", (0.60, 0.60, 0.60), 0.3)


#: Label colours for label maps without a table (label k uses LABEL_COLORS[(k - 1) % len]).
LABEL_COLORS = [(0.90, 0.30, 0.25), (0.30, 0.65, 0.90), (0.95, 0.80, 0.30), (0.45, 0.80, 0.40), (0.70, 0.45, 0.85),
                (0.95, 0.55, 0.20), (0.35, 0.85, 0.80), (0.85, 0.40, 0.60), (0.60, 0.60, 0.60), (0.55, 0.35, 0.20)]


class Tissue(NamedTuple):
    """One class of a label map: its codes, its look, and ``key`` naming it (a part key: letters, digits, _)."""
    name: str
    key: str
    codes: List[int]
    color: Tuple[float, float, float]
    opacity: float
    visible: bool


def read_tissue_table(path: str) -> Dict[int, str]:
    """Code -> tissue name from a TSV or CSV file: the first column the code (an integer), the second the name;
    a header line and blank lines are skipped. Raises FileFormatError-style ``VolrigError`` on a malformed row."""
    table: Dict[int, str] = {}
    with open(path, newline="", encoding="utf-8") as f:
        text = f.read()
    dialect = "excel-tab" if "\t" in text.split("\n", 1)[0] else "excel"
    for n, row in enumerate(csv.reader(text.splitlines(), dialect), start=1):
        if not row or not "".join(row).strip():
            continue
        try:
            code = int(row[0].strip())
        except ValueError:
            if n == 1:
                continue  # the header
            raise VolrigError(f"{path}: line {n}: {row[0]!r} is not an integer tissue code") from None
        if len(row) < 2 or not row[1].strip():
            raise VolrigError(f"{path}: line {n}: code {code} has no tissue name")
        if code in table:
            raise VolrigError(f"{path}: line {n}: code {code} appears twice")
        table[code] = row[1].strip()
    if not table:
        raise VolrigError(f"{path}: no tissue codes")
    return table


def find_tissue_table(path: str, codes) -> str:
    """The tissue table beside a label map's file, or "": a ``.tsv``, ``.csv`` or ``.txt`` file in the same folder
    whose name says "tissue" or "label", that reads as a table and names at least 90% of the non-zero ``codes``
    present (the first such file by name)."""
    import os
    folder = os.path.dirname(os.path.abspath(path))
    wanted = {int(c) for c in np.asarray(codes).ravel() if c != 0 and c == int(c)}
    try:
        names = sorted(os.listdir(folder))
    except OSError:
        return ""
    for name in names:
        low = name.lower()
        if not low.endswith((".tsv", ".csv", ".txt")) or not ("tissue" in low or "label" in low):
            continue
        try:
            table = read_tissue_table(os.path.join(folder, name))
        except (OSError, UnicodeDecodeError, VolrigError):
            continue
        if wanted and len(wanted & set(table)) >= 0.9 * len(wanted):
            return os.path.join(folder, name)
    return ""


def outside_codes(table: Dict[int, str]) -> List[int]:
    """The table's codes that are not body: 0 and those named like external air (``OUTSIDE_NAMES``)."""
    return sorted({0} | {c for c, name in table.items() if re.search(OUTSIDE_NAMES, name, re.I)})


def codes_present(array) -> np.ndarray:
    """``np.unique(array)`` a slab of about 16 M values at a time: no sorted copy of a whole 1 mm body."""
    a = np.asarray(array)
    if a.ndim < 2 or not a.size:
        return np.unique(a)
    step = max(1, (1 << 24) // a[0].size)
    return np.unique(np.concatenate([np.unique(a[z:z + step]) for z in range(0, len(a), step)]))


def body_codes(table: Dict[int, str], present=None) -> List[int]:
    """The table's body codes (not ``outside_codes``), only those in ``present`` when given."""
    keep = None if present is None else {int(c) for c in np.asarray(present).ravel() if c == int(c)}
    outside = set(outside_codes(table))
    return sorted(c for c in table if c not in outside and (keep is None or c in keep))


def tissue_classes(table: Dict[int, str], classes: Sequence[TissueClass] = TISSUE_CLASSES,
                   present: Sequence[int] = None) -> List[Tissue]:
    """The table's body codes grouped by ``classes`` (first match on the name; codes no class matches: "other"),
    ordered by opacity (hidden classes as 0; ties in the classes' order): the order of the ``tissue`` grid's class
    indices (see the module's description). Classes without codes are left out. ``present``: only these codes (e.g.
    ``np.unique`` of the labels)."""
    from .parts import part_key
    codes: Dict[str, List[int]] = {}
    for code in body_codes(table, present):
        match = next((c for c in classes if c.pattern and re.search(c.pattern, table[code], re.I)), OTHER)
        codes.setdefault(match.name, []).append(int(code))
    found = [Tissue(c.name, part_key(c.name), codes[c.name], tuple(c.color), float(c.opacity), bool(c.visible))
             for c in list(classes) + [OTHER] if c.name in codes]
    return index_order(found)


#: Classes that meet the outside: first in ``index_order`` (class 1 next to the outside's 0), so the body's surface
#: passes through no other class.
OUTER = ("skin",)


def index_order(tissues: Sequence[Tissue]) -> List[Tissue]:
    """``tissues`` in the order of the ``tissue`` grid's class indices: the OUTER classes, then by opacity (hidden
    classes as 0; ties in the given order): see the module's description. Order the classes again with the opacities
    a render will use (``tissue_classes`` orders them by the preset's)."""
    return sorted(tissues, key=lambda t: (t.name not in OUTER, t.opacity if t.visible else 0.0))


#: The file metadata entry naming a frame's tissue classes (``classes_metadata``).
METADATA = "volrig_tissues"
#: The label grid of class indices.
GRID = "tissue"


def tissue_grid(labels: Volume, tissues: Sequence[Tissue]) -> Volume:
    """The ``tissue`` grid of a label map: each voxel's class index (uint8, 1-based in the order of ``tissues``, 0 =
    none) on the labels' grid. ``labels``: an integer label map (a frame baked with nearest sampling holds the codes
    themselves). Write it as a label grid (``write_vdb(..., labels=("tissue",))``)."""
    return labels.like(_class_of(_codes(labels.array), tissues))


def brick_classes(brick_values: np.ndarray, tissues: Sequence[Tissue]) -> np.ndarray:
    """``tissue_grid`` of a frame in 8³ bricks (``BrickedFrame.brick_values``: [brick z, y, x, z, y, x]), brick by
    brick: bricks without a code stay zero and untouched, and the temporaries are one brick layer's. Half-float
    values (a bake's) go through one table over their 65,536 bit patterns."""
    out = np.zeros(brick_values.shape, np.uint8)
    half = brick_values.dtype == np.float16
    lut = _half_lut(tissues) if half else class_lut(tissues)
    for z in range(brick_values.shape[0]):
        layer = brick_values[z].reshape(-1, 512)
        used = np.flatnonzero((layer.view(np.uint16) if half else layer).any(axis=1))
        if not len(used):
            continue
        if half:
            cls = lut[layer[used].view(np.uint16)]
            if (cls == _NOT_A_CODE).any():
                raise VolrigError("tissue classes: the labels are not integers (bake label maps with nearest sampling)")
        else:
            cls = _class_of(_codes(layer[used]), tissues, lut)
        out[z].reshape(-1, 512)[used] = cls
    return out


#: ``_half_lut``'s entry for a bit pattern that is no whole number (no class index: at most 254 classes there).
_NOT_A_CODE = 255


def _half_lut(tissues: Sequence[Tissue]) -> np.ndarray:
    """Class (uint8) of each of the 65,536 half-float bit patterns: whole numbers by their code's class,
    others (fractions, infinities, NaN) _NOT_A_CODE."""
    if len(tissues) >= _NOT_A_CODE:
        raise VolrigError(f"tissue classes: {len(tissues)} classes in half-float frames (at most 254)")
    values = np.arange(1 << 16, dtype=np.uint32).astype(np.uint16).view(np.float16).astype(np.float64)
    whole = np.isfinite(values)
    whole[whole] = values[whole] == np.round(values[whole])
    out = np.full(1 << 16, _NOT_A_CODE, np.uint8)
    out[whole] = _class_of(values[whole].astype(np.int64), tissues)
    return out


def _codes(lab: np.ndarray) -> np.ndarray:
    """``lab`` as integer codes: integer arrays as they are, whole-number floats as int32 (else VolrigError)."""
    lab = np.asarray(lab)
    if lab.dtype.kind == "f":
        if not np.all(np.isfinite(lab)) or np.any(lab != np.round(lab)) or np.abs(lab).max(initial=0) >= 2 ** 31:
            raise VolrigError("tissue classes: the labels are not integers (bake label maps with nearest sampling)")
        return lab.astype(np.int32)
    if lab.dtype.kind not in "iub":
        raise VolrigError(f"tissue classes: labels of dtype {lab.dtype} are not integer codes")
    return lab


def class_lut(tissues: Sequence[Tissue]):
    """(codes sorted, their classes) and, when every code is a small non-negative integer, a lookup table code ->
    class (uint8); the classes 1-based in the order of ``tissues``."""
    if len(tissues) > 255:
        raise VolrigError(f"tissue classes: {len(tissues)} classes (at most 255)")
    codes = np.array([c for t in tissues for c in t.codes], dtype=np.int64)
    owner = np.array([k + 1 for k, t in enumerate(tissues) for _ in t.codes], dtype=np.uint8)
    order = np.argsort(codes, kind="stable")
    codes, owner = codes[order], owner[order]
    table = None
    if len(codes) and codes[0] >= 0 and codes[-1] < 1 << 20:
        table = np.zeros(int(codes[-1]) + 2, np.uint8)  # (the last entry: every code beyond, none)
        table[codes] = owner
    return codes, owner, table


def _class_of(lab: np.ndarray, tissues: Sequence[Tissue], lut=None) -> np.ndarray:
    """Each voxel's class (1-based, 0 = none), uint8, of integer codes ``lab``: a lookup table over the codes when
    they are small non-negative integers, else a search among the classes' sorted codes."""
    codes, owner, table = class_lut(tissues) if lut is None else lut
    if not len(codes):
        return np.zeros(lab.shape, np.uint8)
    if table is not None and lab.size and lab.min() >= 0:
        return table[np.minimum(lab, len(table) - 1)]
    values = lab.astype(np.int64)
    i = np.minimum(np.searchsorted(codes, values), len(codes) - 1)
    return np.where(codes[i] == values, owner[i], 0).astype(np.uint8)


def classes_metadata(tissues: Sequence[Tissue]) -> Dict[str, str]:
    """The file metadata naming the ``tissue`` grid's classes: {METADATA: JSON list, in class-index order, of
    {key, name, color, opacity, visible, codes}} (``classes_from_metadata`` reads it back)."""
    return {METADATA: json.dumps([{"key": t.key, "name": t.name, "color": [round(float(c), 4) for c in t.color],
                                   "opacity": float(t.opacity), "visible": bool(t.visible),
                                   "codes": [int(c) for c in t.codes]} for t in tissues])}


def classes_from_metadata(metadata: Dict[str, str]) -> List[Tissue]:
    """The classes ``classes_metadata`` wrote (class index k + 1 is the list's k-th), [] when the metadata name
    none; VolrigError when the entry is malformed."""
    text = metadata.get(METADATA)
    if not text:
        return []
    try:
        return [Tissue(str(d["name"]), str(d["key"]), [int(c) for c in d["codes"]],
                       tuple(float(c) for c in d["color"][:3]), float(d["opacity"]), bool(d["visible"]))
                for d in json.loads(text)]
    except (ValueError, TypeError, KeyError, IndexError) as e:
        raise VolrigError(f"the file's tissue classes ({METADATA}) are malformed: {e}") from None


def file_classes(path: str) -> List[Tissue]:
    """The tissue classes an OpenVDB file's metadata names (a frame baked with tissue looks: ``classes_metadata``),
    [] for other files (any other ending: a drawing's image, a folder, a NIfTI)."""
    from .volume import vdb_metadata
    if not os.fspath(path).lower().endswith(".vdb") or os.path.isdir(path):
        return []
    return classes_from_metadata(vdb_metadata(path))


def label_classes(codes) -> List[Tissue]:
    """One class per non-zero integer code (``label_<code>``), for a label map without a table: colours from
    ``LABEL_COLORS`` in turn, all visible and opaque."""
    out = []
    for c in sorted({int(c) for c in np.asarray(codes).ravel() if c == int(c) and c != 0}):
        out.append(Tissue(f"label {c}", f"label_{c}".replace("-", "m"), [c],
                          LABEL_COLORS[(c - 1) % len(LABEL_COLORS)], 1.0, True))
    return out
