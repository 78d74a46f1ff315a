"""Dark discs of a complex image, with touching or merged discs split apart.

Where a card's two views interleave, a disc of one view may touch or overlap a disc of the other: the dark
mask then holds one blob of two discs (a peanut, or a lens-shaped union), which a roundness test throws away
or, worse, keeps with its centre between the two. Each blob is examined with its distance transform: the
distance to the border of a convex region is a concave function, so a single disc (or ellipse) has one
maximum; two maxima farther apart than the smaller one's distance mean two discs, and the blob is split by a
watershed of the distance transform from those maxima (scikit-image). Discs found this way are marked
``crowded``: the other disc runs into their rim. A disc's rays that would run into a neighbouring disc are
not read (:func:`psvs.calibrate.targets.refine_circle`'s ``avoid``), so discs that touch or come close are
located from the rest of their rim: on mv1440 renders within 0.1 px where at least 3/4 of the rim was read
(psvs.calibrate.detect trusts those). Two discs so far on top of each other that their union is convex
stay one blob (psvs.calibrate.detect: "merged").
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from psvs.calibrate.targets import Ellipse, refine_circle


@dataclass(frozen=True, eq=False)
class Disc:
    """One dark disc: its refined ellipse and whether a neighbour disturbs it (``crowded``)."""

    ellipse: Ellipse
    crowded: bool

    @property
    def centre_px(self) -> np.ndarray:
        return self.ellipse.centre_px

    @property
    def radius_px(self) -> float:
        return float(np.mean(self.ellipse.axes_px))


def dark_mask(grey: np.ndarray, max_diameter_px: float) -> np.ndarray | None:
    """The dark-blob mask (uint8 0/255): black-hat (closing minus image) over a kernel wider than the
    largest disc, Otsu's threshold; None when nothing stands out (a blank image)."""
    k = 2 * (int(np.ceil(max_diameter_px)) // 2) + 3
    kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (k, k))
    hat = cv2.morphologyEx(grey, cv2.MORPH_BLACKHAT, kernel)
    if hat.max() < 20:
        return None
    _, mask = cv2.threshold(hat, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    # blur leaves a 1-2 px low seam where another view's card edge crosses a disc: close it
    return cv2.morphologyEx(mask, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3)))


def _split(component: np.ndarray) -> list[np.ndarray]:
    """The discs of one blob's mask (cropped, bool): itself, or its watershed parts when its distance
    transform has two or more maxima farther apart than the smaller maximum's distance."""
    from scipy import ndimage
    from skimage.segmentation import watershed
    dist = cv2.distanceTransform(component.astype(np.uint8), cv2.DIST_L2, 5)
    top = float(dist.max())
    peaks = (dist == ndimage.maximum_filter(dist, size=3)) & (dist >= 0.5 * top) & component
    labels, n = ndimage.label(peaks, structure=np.ones((3, 3)))
    if n < 2:
        return [component]
    idx = np.arange(1, n + 1)
    height = np.asarray(ndimage.maximum(dist, labels, idx))
    where = np.asarray(ndimage.center_of_mass(peaks, labels, idx))
    kept: list[int] = []
    for k in np.argsort(-height):                  # the highest maxima first, each far from those kept
        if all(np.linalg.norm(where[k] - where[j]) > min(height[k], height[j]) for j in kept):
            kept.append(int(k))
    if len(kept) < 2:
        return [component]
    markers = np.zeros(component.shape, np.int32)
    for m, k in enumerate(kept, 1):
        markers[labels == idx[k]] = m
    parts = watershed(-dist, markers, mask=component)
    return [parts == m for m in range(1, len(kept) + 1)]


def find_discs(grey: np.ndarray, diameter_px: tuple[float, float]) -> list[Disc]:
    """Dark discs whose image is ``diameter_px`` (smallest, largest) across, touching ones split apart,
    each refined to sub-pixel (:func:`psvs.calibrate.targets.refine_circle`)."""
    lo, hi = diameter_px
    mask = dark_mask(grey, hi)
    if mask is None:
        return []
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    min_area = 0.5 * np.pi * (lo / 2) ** 2
    found = []                                  # (centre, radius, split from a blob of several)
    for k in range(1, n):
        x, y, w, h, area = stats[k]
        if area < min_area or max(w, h) > 2.6 * hi:
            continue
        comp = labels[y:y + h, x:x + w] == k
        parts = _split(np.pad(comp, 1))
        for part in parts:
            a = int(part.sum())
            if a < min_area:
                continue
            vs, us = np.nonzero(part)
            contour, _ = cv2.findContours(part.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
            hull = cv2.contourArea(cv2.convexHull(max(contour, key=len)))
            if hull <= 0 or a / hull < 0.8 or np.sqrt(4 * a / np.pi) > 1.2 * hi:
                continue                        # not a disc (a card's corner, a dark gap, a big shadow)
            found.append((np.array([us.mean() + x - 1, vs.mean() + y - 1]), np.sqrt(a / np.pi), len(parts) > 1))
    blobs = np.array([(*c, r) for c, r, _ in found]).reshape(-1, 3)
    discs = []
    for k, (centre, radius, split) in enumerate(found):
        near = np.linalg.norm(blobs[:, :2] - centre, axis=1) < 2.5 * radius + blobs[:, 2] + 4.0
        near[k] = False
        try:
            discs.append(Disc(refine_circle(grey, centre, radius, avoid=blobs[near]), split))
        except ValueError:
            continue                            # too few rim points: not a disc one can locate
    return discs
