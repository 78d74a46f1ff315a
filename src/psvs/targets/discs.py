"""Dark discs of a complex image: the one blob finder of psvs's targets.

Every target psvs reads is dark discs on a light ground: the paper's accuracy pattern (Fig. 9,
:mod:`psvs.targets.pattern`) and the circle-grid cards (:mod:`psvs.targets.detect`, :mod:`psvs.targets.grid`).
Dark blobs are found with a black-hat transform (closing minus image) over a kernel wider than the largest
disc and Otsu's threshold (:func:`dark_mask`), so they stand out on any local background, including where
one view's disc lies on the other view's sheet. The pattern reads the mask's outlines
(:func:`blob_contours`, :func:`dark_blobs`, :func:`split_two_discs`); the cards its discs, touching ones
split apart (:func:`find_discs`). Each disc is then refined to sub-pixel (:func:`psvs.targets.rim.refine_circle`).

Where a card's two views interleave, a disc of one view may touch or overlap a disc of the other: the dark
mask then holds one blob of two discs (a peanut, or a lens-shaped union), which a roundness test throws away
or, worse, keeps with its centre between the two. Each blob is examined with its distance transform: the
distance to the border of a convex region is a concave function, so a single disc (or ellipse) has one
maximum; two maxima farther apart than the smaller one's distance mean two discs, and the blob is split by a
watershed of the distance transform from those maxima (scikit-image). Discs found this way are marked
``crowded``: the other disc runs into their rim. A disc's rays that would run into a neighbouring disc are
not read (:func:`psvs.targets.rim.refine_circle`'s ``avoid``), so discs that touch or come close are
located from the rest of their rim: on mv1440 renders within 0.1 px where at least 3/4 of the rim was read
(psvs.targets.detect trusts those). Two discs so far on top of each other that their union is convex
stay one blob (psvs.targets.detect: "merged").
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from psvs.targets.rim import Ellipse, refine_circle

#: The discs the detector finds: at most this wide (its black-hat kernel) and at least this large in area
#: (smaller blobs are noise), px: a disc whose image lies outside is never detected.
MAX_DIAMETER_PX = 40
MIN_AREA_PX = 12.0


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


def blob_contours(grey: np.ndarray, max_diameter_px: int = MAX_DIAMETER_PX, min_area_px: float = MIN_AREA_PX):
    """Dark blobs of at least ``min_area_px`` narrower than ``max_diameter_px`` (black-hat, Otsu): list of
    (contour (K, 2) px, area px, roundness 4 pi area / perimeter^2)."""
    mask = dark_mask(grey, max_diameter_px)
    if mask is None:
        return []
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    out = []
    for c in contours:
        area = cv2.contourArea(c)
        per = cv2.arcLength(c, True)
        if area >= min_area_px and per > 0:
            out.append((c.reshape(-1, 2).astype(np.float64), float(area), float(4 * np.pi * area / per ** 2)))
    return out


def blob_centre(contour: np.ndarray) -> np.ndarray:
    """The centroid (u, v) px of a blob's outline (K, 2) px (its area moments)."""
    m = cv2.moments(contour.astype(np.float32).reshape(-1, 1, 2))
    return np.array([m["m10"] / m["m00"], m["m01"] / m["m00"]])


def dark_blobs(grey: np.ndarray, max_diameter_px: int = MAX_DIAMETER_PX, min_area_px: float = MIN_AREA_PX):
    """Candidate dark round blobs (:func:`blob_contours`, roundness >= 0.6): list of (centre (2,),
    equivalent radius px)."""
    return [(blob_centre(c), float(np.sqrt(a / np.pi))) for c, a, r in blob_contours(grey, max_diameter_px, min_area_px)
            if r >= 0.6]


def split_two_discs(contour: np.ndarray) -> tuple[tuple[np.ndarray, float], tuple[np.ndarray, float]] | None:
    """Two overlapping discs' (centre (2,), radius px) from the outline of their union (K, 2) px: a
    least-squares fit of two circles (each outline point to the nearer), started along the outline's long
    axis. None when the outline is one disc (the centres closer than a third of a radius)."""
    from scipy.optimize import least_squares
    p = contour
    m = p.mean(axis=0)
    _, _, vt = np.linalg.svd(p - m)
    along, across = (p - m) @ vt[0], (p - m) @ vt[1]
    r0 = 0.5 * float(np.ptp(across))
    half = max(0.5 * float(np.ptp(along)) - r0, 0.2 * r0)
    x0 = np.concatenate([m - half * vt[0], [r0], m + half * vt[0], [r0]])

    def res(x):
        d1 = np.linalg.norm(p - x[:2], axis=1) - x[2]
        d2 = np.linalg.norm(p - x[3:5], axis=1) - x[5]
        return np.where(np.abs(d1) < np.abs(d2), d1, d2)

    x = least_squares(res, x0, loss="soft_l1", f_scale=1.0).x
    if np.linalg.norm(x[:2] - x[3:5]) < min(x[2], x[5]) / 3 or min(x[2], x[5]) <= 0:
        return None
    return (x[:2], float(x[2])), (x[3:5], float(x[5]))


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
    each refined to sub-pixel (:func:`psvs.targets.rim.refine_circle`)."""
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
