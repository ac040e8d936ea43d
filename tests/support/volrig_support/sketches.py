"""Procedural drawings (RGB float images, white background, dark outlines) for the tests and pictures of
``volrig.drawing``: shapes are painted in order, each over what is there, like strokes on paper.

- ``quadruped``: a side view: far legs behind the belly, body, tail, near legs drawn over the belly, neck, head.
- ``arm_across``: a body with an arm drawn across it (the hand beyond its outline).
- ``character``: a front-view humanoid: head, torso, arms hanging beside it, legs; the right forearm crosses the
  belly when ``arm_over`` is set.
- ``disc``, ``bar``: one filled shape.
"""
from __future__ import annotations

import numpy as np

from volrig._optional import LazyModule

ndi = LazyModule("scipy.ndimage", "volrig_support.sketches (the procedural test drawings)")

OUTLINE = (0.05, 0.05, 0.05)


def canvas(h: int, w: int) -> np.ndarray:
    return np.ones((h, w, 3))


def paint(img: np.ndarray, shape: np.ndarray, fill, line: int = 2) -> np.ndarray:
    """Paints ``shape`` with ``fill`` and a dark outline ``line`` pixels wide over what is there."""
    img[shape] = fill
    if line:
        img[shape & ~ndi.binary_erosion(shape, iterations=line)] = OUTLINE
    return img


def ellipse(h, w, cy, cx, ry, rx) -> np.ndarray:
    y, x = np.mgrid[:h, :w]
    return ((y - cy) / ry) ** 2 + ((x - cx) / rx) ** 2 <= 1


def box(h, w, y0, y1, x0, x1) -> np.ndarray:
    m = np.zeros((h, w), bool)
    m[y0:y1, x0:x1] = True
    return m


def band(h, w, p, q, r) -> np.ndarray:
    """Pixels within ``r`` of the segment p-q ((row, column) points)."""
    y, x = np.mgrid[:h, :w]
    p, q = np.asarray(p, float), np.asarray(q, float)
    d = q - p
    t = np.clip(((y - p[0]) * d[0] + (x - p[1]) * d[1]) / (d @ d), 0, 1)
    return (y - p[0] - t * d[0]) ** 2 + (x - p[1] - t * d[1]) ** 2 <= r * r


def disc(r: int = 30, pad: int = 10, fill=(0.8, 0.3, 0.3)) -> np.ndarray:
    n = 2 * (r + pad)
    return paint(canvas(n, n), ellipse(n, n, n / 2, n / 2, r, r), fill, line=0)


def bar(length: int = 120, r: int = 15, pad: int = 10) -> np.ndarray:
    h, w = 2 * (r + pad), length + 2 * pad
    return paint(canvas(h, w), box(h, w, pad, pad + 2 * r, pad, pad + length), (0.3, 0.6, 0.3), line=0)


def quadruped(h: int = 170, w: int = 250, offset: int = 6, leg: int = 8) -> np.ndarray:
    img = canvas(h, w)
    coat, shade = (0.75, 0.55, 0.3), (0.6, 0.42, 0.22)
    for x in (65, 165):
        paint(img, box(h, w, 80, 150, x + offset - leg, x + offset + leg), shade)  # far legs
    paint(img, band(h, w, (70, 45), (40, 15), 5), coat)  # tail
    paint(img, ellipse(h, w, 72, 115, 25, 70), coat)  # body
    for x in (65, 165):
        paint(img, box(h, w, 62, 155, x - leg, x + leg), coat)  # near legs, over the belly
    paint(img, band(h, w, (60, 175), (40, 195), 12), coat)  # neck
    paint(img, ellipse(h, w, 35, 205, 16, 20), coat)  # head
    return img


def arm_across(h: int = 200, w: int = 160, line: int = 2) -> np.ndarray:
    img = canvas(h, w)
    paint(img, ellipse(h, w, 100, 80, 80, 45), (0.4, 0.6, 0.9), line)  # body
    paint(img, band(h, w, (50, 40), (150, 150), 10), (0.9, 0.7, 0.6), line)  # arm over it, the hand beyond
    return img


def character(h: int = 300, w: int = 200, arm_over: bool = False) -> np.ndarray:
    """A front-view humanoid, feet apart, arms hanging beside the torso (image right = the character's left)."""
    img = canvas(h, w)
    skin, shirt, trousers, shoes = (0.95, 0.78, 0.62), (0.85, 0.25, 0.2), (0.2, 0.3, 0.6), (0.3, 0.2, 0.15)
    c = w // 2
    for s in (-1, 1):
        paint(img, band(h, w, (165, c + s * 18), (272, c + s * 30), 13), trousers)  # legs
        paint(img, ellipse(h, w, 282, c + s * 34, 9, 16), shoes)
        if not (arm_over and s < 0):
            paint(img, band(h, w, (85, c + s * 38), (175, c + s * 58), 10), shirt)  # arms
            paint(img, ellipse(h, w, 185, c + s * 60, 11, 10), skin)  # hands
    paint(img, ellipse(h, w, 125, c, 60, 36), shirt)  # torso
    paint(img, box(h, w, 52, 72, c - 9, c + 9), skin)  # neck
    paint(img, ellipse(h, w, 40, c, 27, 23), skin)  # head
    if arm_over:  # the right arm bent across the belly, drawn over it
        paint(img, band(h, w, (85, c - 38), (130, c - 50), 10), shirt)
        paint(img, band(h, w, (135, c - 48), (140, c + 20), 9), shirt)
        paint(img, ellipse(h, w, 140, c + 26, 10, 11), skin)
    return img
