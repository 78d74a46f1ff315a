"""Surface textures: albedo in [0, 1] as a function of a surface's local (x, y) coordinates in mm.

Textures are evaluated analytically at each ray's exact hit point (anti-aliasing comes from the
renderer's supersampling). Image textures are sampled bilinearly and stretched over the object's
``size_mm`` (rectangles) or its local bounding square.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from psvs._validate import check_count, check_finite, check_positive
from psvs.simulate.kernels import bilinear_texture, value_noise


def _check_levels(**levels):
    for name, v in levels.items():
        if not 0.0 <= check_finite(v, name) <= 1.0:
            raise ValueError(f"{name} must be an albedo in [0, 1], got {v!r}")


@dataclass(frozen=True)
class Uniform:
    """A plain surface: one albedo (0-1) everywhere."""

    albedo: float = 0.8

    def __post_init__(self):
        _check_levels(albedo=self.albedo)

    def __call__(self, xy_mm: np.ndarray) -> np.ndarray:
        return np.full(len(xy_mm), self.albedo)


@dataclass(frozen=True)
class Checker:
    """Squares of ``square_mm``; the square at the origin's +x/+y corner is ``high``."""

    square_mm: float = 20.0
    low: float = 0.1
    high: float = 0.9

    def __post_init__(self):
        check_positive(self.square_mm, "square_mm", "mm")
        _check_levels(low=self.low, high=self.high)

    def __call__(self, xy_mm):
        k = np.floor(xy_mm[:, 0] / self.square_mm) + np.floor(xy_mm[:, 1] / self.square_mm)
        return np.where(k % 2 == 0, self.high, self.low)


def _points(xy_mm) -> np.ndarray:
    """Local points (N, 2) mm as the texture kernels take them (float64, rows contiguous)."""
    return np.ascontiguousarray(xy_mm, dtype=np.float64)


@functools.lru_cache(maxsize=16)
def _lattice(seed: int) -> np.ndarray:
    """A seeded random lattice, 1024 x 1024 values in [0, 1), repeated periodically."""
    return np.random.default_rng(seed).random((1024, 1024))


@dataclass(frozen=True)
class Noise:
    """Smooth value noise between low and high: smoothstep-bilinear interpolation of a seeded random
    lattice of pitch ``scale_mm`` (period 1024 pitches)."""

    scale_mm: float = 10.0
    seed: int = 0
    low: float = 0.1
    high: float = 0.9

    def __post_init__(self):
        check_positive(self.scale_mm, "scale_mm", "mm")
        if not isinstance(self.seed, int) or isinstance(self.seed, bool):
            raise TypeError(f"seed must be an integer, got {self.seed!r}")
        _check_levels(low=self.low, high=self.high)

    def __call__(self, xy_mm):
        return value_noise(_lattice(self.seed), _points(xy_mm), float(self.scale_mm), float(self.low),
                           float(self.high))


#: Most circles in a :class:`Circles` row (the paper's pattern has 5).
MAX_CIRCLES = 1000


@dataclass(frozen=True)
class Circles:
    """A row of ``count`` discs of ``diameter_mm``, centres ``spacing_mm`` apart along local x and centred
    on the origin, colour ``low``, on a ground of ``high`` (the paper's Fig. 9 pattern: 5 x 10 mm, 20 mm)."""

    diameter_mm: float = 10.0
    spacing_mm: float = 20.0
    count: int = 5
    low: float = 0.05
    high: float = 0.9

    def __post_init__(self):
        check_positive(self.diameter_mm, "diameter_mm", "mm")
        check_positive(self.spacing_mm, "spacing_mm", "mm")
        check_count(self.count, "count", 1)
        if self.count > MAX_CIRCLES:
            raise ValueError(f"count must be at most {MAX_CIRCLES} circles in a row, got {self.count}")
        _check_levels(low=self.low, high=self.high)

    def centres_mm(self) -> np.ndarray:
        """Circle centres in local coordinates, shape (count, 2), mm."""
        x = (np.arange(self.count) - (self.count - 1) / 2) * self.spacing_mm
        return np.column_stack([x, np.zeros(self.count)])

    def __call__(self, xy_mm):
        # the centres lie on one line: a point inside any (equal) disc is inside the one whose centre is nearest
        # along the line, so one test a point, whatever the count
        half = (self.count - 1) / 2
        k = np.clip(np.rint(xy_mm[:, 0] / self.spacing_mm + half), 0, self.count - 1)
        cx = (k - half) * self.spacing_mm
        inside = (xy_mm[:, 0] - cx) ** 2 + xy_mm[:, 1] ** 2 <= (self.diameter_mm / 2) ** 2
        return np.where(inside, self.low, self.high)


@dataclass(frozen=True)
class Chessboard:
    """A calibration chessboard: ``squares_x`` x ``squares_y`` squares of ``square_mm`` centred on the
    origin (its (squares_x - 1) x (squares_y - 1) inner corners at multiples of the square size), on a
    ``high`` (white) margin, as OpenCV's detector needs."""

    squares_x: int = 6
    squares_y: int = 5
    square_mm: float = 10.0
    low: float = 0.05
    high: float = 0.9

    def __post_init__(self):
        check_count(self.squares_x, "squares_x", 3)
        check_count(self.squares_y, "squares_y", 3)
        check_positive(self.square_mm, "square_mm", "mm")
        _check_levels(low=self.low, high=self.high)

    def __call__(self, xy_mm):
        s = self.square_mm
        gx = np.floor(xy_mm[:, 0] / s + self.squares_x / 2)
        gy = np.floor(xy_mm[:, 1] / s + self.squares_y / 2)
        on = (gx >= 0) & (gx < self.squares_x) & (gy >= 0) & (gy < self.squares_y)
        dark = on & ((gx + gy) % 2 == 0)
        return np.where(dark, self.low, self.high)


@dataclass(frozen=True)
class CircleGrid:
    """An OpenCV-style symmetric grid of ``rows`` x ``cols`` dark discs (``diameter_mm``, centres
    ``spacing_mm`` apart), centred on the origin, colour ``low`` on a ground of ``high``."""

    rows: int = 4
    cols: int = 5
    spacing_mm: float = 15.0
    diameter_mm: float = 7.0
    low: float = 0.05
    high: float = 0.9

    def __post_init__(self):
        _check_disc_grid(self, 2, self.spacing_mm, "spacing_mm")

    def centres_mm(self) -> np.ndarray:
        """Disc centres (rows * cols, 2) mm, row by row (OpenCV's object-point order)."""
        j, i = np.meshgrid(np.arange(self.cols), np.arange(self.rows))
        return np.column_stack([(j.ravel() - (self.cols - 1) / 2) * self.spacing_mm,
                                (i.ravel() - (self.rows - 1) / 2) * self.spacing_mm])

    def __call__(self, xy_mm):
        s = self.spacing_mm
        gx = np.rint(xy_mm[:, 0] / s + (self.cols - 1) / 2)
        gy = np.rint(xy_mm[:, 1] / s + (self.rows - 1) / 2)
        on = (gx >= 0) & (gx < self.cols) & (gy >= 0) & (gy < self.rows)
        dx = xy_mm[:, 0] - (gx - (self.cols - 1) / 2) * s
        dy = xy_mm[:, 1] - (gy - (self.rows - 1) / 2) * s
        inside = on & (dx * dx + dy * dy <= (self.diameter_mm / 2) ** 2)
        return np.where(inside, self.low, self.high)


def _check_disc_grid(grid, min_rows: int, nearest_mm: float, nearest_name: str) -> None:
    """A circle grid's fields: rows >= ``min_rows``, cols >= 2, positive sizes, discs narrower than the
    nearest neighbours' distance ``nearest_mm`` (named ``nearest_name``), levels in [0, 1]."""
    check_count(grid.rows, "rows", min_rows)
    check_count(grid.cols, "cols", 2)
    check_positive(grid.spacing_mm, "spacing_mm", "mm")
    check_positive(grid.diameter_mm, "diameter_mm", "mm")
    if grid.diameter_mm >= nearest_mm:
        raise ValueError(f"diameter_mm must be < {nearest_name}, got {grid.diameter_mm!r} >= {nearest_mm:.4g}")
    _check_levels(low=grid.low, high=grid.high)


@dataclass(frozen=True)
class AsymmetricCircleGrid:
    """OpenCV's asymmetric circle grid: ``rows`` rows of ``cols`` dark discs (``diameter_mm``); disc (r, c) at
    ((2 c + r mod 2) s, r s) with s = ``spacing_mm`` (OpenCV's unit: rows s apart, discs along a row 2 s apart,
    nearest neighbours s sqrt 2 apart), centred on the origin, colour ``low`` on a ground of ``high``."""

    rows: int = 7
    cols: int = 4
    spacing_mm: float = 10.0
    diameter_mm: float = 8.0
    low: float = 0.05
    high: float = 0.9

    def __post_init__(self):
        _check_disc_grid(self, 3, self.spacing_mm * np.sqrt(2), "spacing_mm * sqrt(2) (nearest neighbours' distance)")

    def lattice(self) -> np.ndarray:
        """Disc positions in units of ``spacing_mm``, (rows * cols, 2) int, OpenCV's order (row by row)."""
        c, r = np.meshgrid(np.arange(self.cols), np.arange(self.rows))
        return np.column_stack([2 * c.ravel() + r.ravel() % 2, r.ravel()])

    def centres_mm(self) -> np.ndarray:
        """Disc centres (rows * cols, 2) mm, OpenCV's order, centred on the origin."""
        g = self.lattice().astype(float)
        return (g - 0.5 * (g.max(axis=0) + g.min(axis=0))) * self.spacing_mm

    def __call__(self, xy_mm):
        c = self.centres_mm()
        s = self.spacing_mm
        # the nearest disc: rows are s apart; within a row discs are 2 s apart, odd rows shifted by s
        gy = np.rint((xy_mm[:, 1] - c[0, 1]) / s)
        shift = np.where(gy % 2 == 1, s, 0.0)
        gx = np.rint((xy_mm[:, 0] - c[0, 0] - shift) / (2 * s))
        on = (gy >= 0) & (gy < self.rows) & (gx >= 0) & (gx < self.cols)
        dx = xy_mm[:, 0] - (c[0, 0] + shift + 2 * s * gx)
        dy = xy_mm[:, 1] - (c[0, 1] + s * gy)
        inside = on & (dx * dx + dy * dy <= (self.diameter_mm / 2) ** 2)
        return np.where(inside, self.low, self.high)


#: The ArUco dictionaries a ChArUco board may use (OpenCV's predefined names).
ARUCO_DICTIONARIES = ("DICT_4X4_50", "DICT_4X4_100", "DICT_5X5_50", "DICT_5X5_100", "DICT_6X6_50",
                      "DICT_6X6_250")


@functools.lru_cache(maxsize=8)
def aruco_cells(dictionary: str, count: int) -> np.ndarray:
    """The first ``count`` markers of an OpenCV ArUco dictionary as cells, (count, n + 2, n + 2) bool (True
    white), n the marker's bits per side, with OpenCV's one-cell black border."""
    import cv2
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
    n = d.markerSize + 2
    if count > d.bytesList.shape[0]:
        raise ValueError(f"{dictionary} holds {d.bytesList.shape[0]} markers, the board needs {count}")
    return np.stack([d.generateImageMarker(k, n, borderBits=1) > 127 for k in range(count)])


@dataclass(frozen=True)
class CharucoBoard:
    """OpenCV's ChArUco board (cv2.aruco.CharucoBoard, its layout as OpenCV >= 4.6 draws it): ``squares_x``
    x ``squares_y`` chessboard squares of ``square_mm``, the top-left one black, and in each white square an
    ArUco marker of ``marker_mm`` from ``dictionary`` (ids 0, 1, ... row by row), centred on the origin
    (OpenCV's board x and y, here shifted by half the board)."""

    squares_x: int = 7
    squares_y: int = 5
    square_mm: float = 20.0
    marker_mm: float = 15.0
    dictionary: str = "DICT_4X4_50"
    low: float = 0.05
    high: float = 0.9

    def __post_init__(self):
        check_count(self.squares_x, "squares_x", 3)
        check_count(self.squares_y, "squares_y", 3)
        check_positive(self.square_mm, "square_mm", "mm")
        check_positive(self.marker_mm, "marker_mm", "mm")
        if self.marker_mm >= self.square_mm:
            raise ValueError(f"marker_mm must be < square_mm, got {self.marker_mm!r} >= {self.square_mm!r}")
        if self.dictionary not in ARUCO_DICTIONARIES:
            raise ValueError(f"dictionary must be one of {', '.join(ARUCO_DICTIONARIES)}, got {self.dictionary!r}")
        _check_levels(low=self.low, high=self.high)

    @property
    def marker_count(self) -> int:
        return (self.squares_x * self.squares_y) // 2

    def corners_mm(self) -> np.ndarray:
        """The inner chessboard corners ((squares_x - 1) * (squares_y - 1), 2) mm, OpenCV's ChArUco ids'
        order (row by row), centred on the origin."""
        j, i = np.meshgrid(np.arange(1, self.squares_x), np.arange(1, self.squares_y))
        return np.column_stack([(j.ravel() - self.squares_x / 2) * self.square_mm,
                                (i.ravel() - self.squares_y / 2) * self.square_mm])

    def __call__(self, xy_mm):
        s = self.square_mm
        bx = xy_mm[:, 0] / s + self.squares_x / 2          # board coordinates in squares, from the top-left
        by = xy_mm[:, 1] / s + self.squares_y / 2
        gx, gy = np.floor(bx).astype(np.int64), np.floor(by).astype(np.int64)
        on = (gx >= 0) & (gx < self.squares_x) & (gy >= 0) & (gy < self.squares_y)
        white = on & ((gx + gy) % 2 == 1)
        cells = aruco_cells(self.dictionary, self.marker_count)
        n = cells.shape[1]
        margin = 0.5 * (1 - self.marker_mm / s)
        mx = (bx - gx - margin) / (1 - 2 * margin)          # position in the marker, 0..1
        my = (by - gy - margin) / (1 - 2 * margin)
        in_marker = white & (mx >= 0) & (mx < 1) & (my >= 0) & (my < 1)
        out = np.where(on & ~white, self.low, self.high)
        k = np.flatnonzero(in_marker)
        ids = (gy[k] * self.squares_x + gx[k]) // 2         # white squares row by row
        cx = np.minimum((mx[k] * n).astype(np.int64), n - 1)
        cy = np.minimum((my[k] * n).astype(np.int64), n - 1)
        out[k] = np.where(cells[ids, cy, cx], self.high, self.low)
        return out


@dataclass(frozen=True, eq=False)
class ImageTexture:
    """A grey image (H, W) in [0, 1] stretched over ``size_mm`` (width, height) centred on the origin.
    Image row 0 is at local -y/2 (top, toward smaller image rows when the object faces the camera)."""

    image: np.ndarray
    size_mm: tuple[float, float]
    path: str = ""

    def __call__(self, xy_mm):
        return bilinear_texture(self.image, _points(xy_mm), float(self.size_mm[0]), float(self.size_mm[1]))


Texture = (Uniform | Checker | Chessboard | Noise | Circles | CircleGrid | AsymmetricCircleGrid | CharucoBoard
           | ImageTexture)
