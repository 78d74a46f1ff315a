"""The PSVS rig as frozen dataclasses: camera, the four mirrors and the M1 glass plate.

Frame C (DEVELOPERS.md): origin at the real camera's optical centre O, Z along the optical axis toward
the scene, X toward increasing image column u, Y toward increasing row v. Lengths in mm, angles in rad.

Layout (paper Fig. 1, omega_1 = 45 deg): M1's coated front face crosses the axis at z = c1 and reflects
toward +X; M4 (parallel to M1, at x = +b/2) turns that path to +Z: the *right* view, virtual centre
O2 = (+b/2, 0, -b/2). Light transmitted through the M1 plate meets M2 (z = c2), goes to -X, and M3
(parallel to M2, at x = -b/2) turns it to +Z: the *left* view, virtual centre O1 = (-b/2, 0, -b/2).

A real build departs from that design (docs/optics.md, "The rig as built"): each mirror may be tilted about
its two in-plane axes and shifted along its normal (:class:`MirrorError`; M1's plate keeps its faces
parallel), the whole mirror box may be turned about O relative to the camera (``box_rotation_rad``), and
the lens has OpenCV's five distortion coefficients. All of them default to the ideal rig.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from psvs._validate import check_finite, check_nonnegative, check_pair, check_positive

MIRROR_NAMES = ("m1", "m2", "m3", "m4")


@dataclass(frozen=True)
class Camera:
    """The real camera: a pinhole with square-or-not pixels and OpenCV's lens model.

    Sensor coordinates (mm) of pixel (u, v): ``x = (u - cx) * pitch_x``, ``y = (v - cy) * pitch_y``;
    pixel centres sit at integer (u, v). Lens distortion is OpenCV's (Brown-Conrady) with
    ``distortion = (k1, k2, p1, p2, k3)``: an ideal ray (x, y) = (X/Z, Y/Z), r^2 = x^2 + y^2, lands at
    x_d = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2),
    y_d = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y, then x = f x_d (mm).
    ``relative_illumination = (a2, a4)``: the lens's fall-off of light away from the axis,
    RI = 1 + a2 rho^2 + a4 rho^4 with rho = sqrt(x_d^2 + y_d^2) (:mod:`psvs.optics.illumination`); (0, 0) is flat.
    """

    focal_length_mm: float = 11.3
    pixel_pitch_mm: tuple[float, float] = (0.01, 0.01)      # x, y
    image_size_px: tuple[int, int] = (640, 480)              # width, height
    principal_point_px: tuple[float, float] = (319.5, 239.5)  # cx, cy
    distortion: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)  # k1, k2, p1, p2, k3 (OpenCV's order)
    relative_illumination: tuple[float, float] = (0.0, 0.0)    # a2, a4 of RI(rho) = 1 + a2 rho^2 + a4 rho^4

    def __post_init__(self):
        check_positive(self.focal_length_mm, "focal_length_mm", "mm")
        px, py = check_pair(self.pixel_pitch_mm, "pixel_pitch_mm")
        check_positive(px, "pixel_pitch_mm[0]", "mm")
        check_positive(py, "pixel_pitch_mm[1]", "mm")
        size = self.image_size_px
        if (not isinstance(size, (tuple, list)) or len(size) != 2
                or not all(isinstance(s, int) and not isinstance(s, bool) and s > 0 for s in size)):
            raise ValueError(f"image_size_px must be two positive integers (width, height), got {size!r}")
        check_pair(self.principal_point_px, "principal_point_px")
        dist = self.distortion
        if not isinstance(dist, (tuple, list)) or len(dist) != 5:
            raise ValueError(f"distortion must be five numbers (k1, k2, p1, p2, k3), got {dist!r}")
        object.__setattr__(self, "distortion", tuple(check_finite(c, f"distortion[{k}]") for k, c in enumerate(dist)))
        object.__setattr__(self, "relative_illumination",
                           check_pair(self.relative_illumination, "relative_illumination"))
        object.__setattr__(self, "pixel_pitch_mm", (px, py))
        object.__setattr__(self, "image_size_px", (int(size[0]), int(size[1])))
        object.__setattr__(self, "principal_point_px", tuple(float(c) for c in self.principal_point_px))

    @property
    def distorted(self) -> bool:
        return any(c != 0.0 for c in self.distortion)

    @property
    def vignetted(self) -> bool:
        """True when the lens's relative illumination is not flat."""
        return self.relative_illumination != (0.0, 0.0)

    @property
    def half_fov_rad(self) -> tuple[float, float]:
        """Half field of view (horizontal a, vertical) of the outer pixel edges, rad."""
        (w, h), (cx, cy), (px, py) = self.image_size_px, self.principal_point_px, self.pixel_pitch_mm
        f = self.focal_length_mm
        ax = max(cx + 0.5, w - 0.5 - cx) * px / f
        ay = max(cy + 0.5, h - 0.5 - cy) * py / f
        return math.atan(ax), math.atan(ay)


@dataclass(frozen=True)
class MirrorExtent:
    """Finite size of one mirror: a rectangle in the mirror's plane.

    Coordinates are measured from the mirror's *anchor* (where the nominal optical axis of its path
    crosses it) along ``s`` (the in-plane horizontal direction, in the XZ plane, with +Z component) and
    ``t`` (= +Y).
    """

    along_mm: tuple[float, float]   # (s_min, s_max)
    height_mm: tuple[float, float]  # (t_min, t_max)

    def __post_init__(self):
        s = check_pair(self.along_mm, "along_mm")
        t = check_pair(self.height_mm, "height_mm")
        if not s[0] < s[1]:
            raise ValueError(f"along_mm must be (min, max) with min < max, got {self.along_mm!r}")
        if not t[0] < t[1]:
            raise ValueError(f"height_mm must be (min, max) with min < max, got {self.height_mm!r}")
        object.__setattr__(self, "along_mm", s)
        object.__setattr__(self, "height_mm", t)

    @property
    def width_mm(self) -> float:
        return self.along_mm[1] - self.along_mm[0]

    @property
    def size_mm(self) -> tuple[float, float]:
        """(width along s, height along Y), mm."""
        return self.width_mm, self.height_mm[1] - self.height_mm[0]

    def scaled(self, factor: float) -> "MirrorExtent":
        """The rectangle scaled about its own centre by ``factor`` (e.g. 0.98 shrinks it by 2 %)."""
        def sc(lo, hi):
            c, h = (lo + hi) / 2, (hi - lo) / 2 * factor
            return (c - h, c + h)
        return MirrorExtent(sc(*self.along_mm), sc(*self.height_mm))


@dataclass(frozen=True)
class MirrorError:
    """How one mirror of a real build departs from its designed pose.

    ``tilt_rad = (a, b)``: the mirror turned about its anchor, first by a about the vertical axis +Y
    (this changes omega_1 in the XZ plane), then by b about its in-plane horizontal axis s (it leans
    forward or back, out of vertical). ``shift_mm``: then moved along its (tilted) normal, which faces the
    light arriving on the nominal path. Zero for the ideal rig.
    """

    tilt_rad: tuple[float, float] = (0.0, 0.0)
    shift_mm: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "tilt_rad", check_pair(self.tilt_rad, "tilt_rad"))
        object.__setattr__(self, "shift_mm", check_finite(self.shift_mm, "shift_mm"))

    @property
    def is_zero(self) -> bool:
        return self.tilt_rad == (0.0, 0.0) and self.shift_mm == 0.0


@dataclass(frozen=True)
class Mirrors:
    """The four mirrors and the M1 plate; symbols as in the paper (b, omega_1, d, n) and eq. (15) (l, m)."""

    baseline_mm: float = 100.0           # b, distance between the two virtual optical axes
    m1_axis_distance_mm: float = 22.0    # c1: M1's coated front face crosses the optical axis at z = c1
    m2_axis_distance_mm: float = 44.0    # c2: M2 crosses the optical axis at z = c2
    angle_rad: float = math.pi / 4       # omega_1: angle between the mirrors and the optical axis
    plate_thickness_mm: float = 3.0      # d, M1 glass thickness
    refractive_index: float = 1.52       # n, M1 glass
    split_ratio: float = 0.5             # share of light reflected at M1 (right view)
    refraction_l_mm: float | None = None  # l of eq. (15); None = derived from d, n, omega_1
    refraction_m_mm: float | None = None  # m of eq. (15); None = derived from d, n, omega_1
    m1_extent: MirrorExtent | None = None  # None = unbounded plane
    m2_extent: MirrorExtent | None = None
    m3_extent: MirrorExtent | None = None
    m4_extent: MirrorExtent | None = None
    m1_error: MirrorError = field(default_factory=MirrorError)
    m2_error: MirrorError = field(default_factory=MirrorError)
    m3_error: MirrorError = field(default_factory=MirrorError)
    m4_error: MirrorError = field(default_factory=MirrorError)
    box_rotation_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)  # rotation vector of the box about O

    def __post_init__(self):
        check_positive(self.baseline_mm, "baseline_mm", "mm")
        c1 = check_positive(self.m1_axis_distance_mm, "m1_axis_distance_mm", "mm")
        c2 = check_positive(self.m2_axis_distance_mm, "m2_axis_distance_mm", "mm")
        if c2 <= c1:
            raise ValueError(
                f"m2_axis_distance_mm must be > m1_axis_distance_mm (M2 sits behind M1), got {c2!r} <= {c1!r}")
        w = check_finite(self.angle_rad, "angle_rad")
        if not 0 < w < math.pi / 2:
            raise ValueError(f"angle_rad (omega_1) must be in (0, pi/2), got {w!r}")
        check_nonnegative(self.plate_thickness_mm, "plate_thickness_mm", "mm")
        n = check_finite(self.refractive_index, "refractive_index")
        if n < 1:
            raise ValueError(f"refractive_index must be >= 1, got {n!r}")
        s = check_finite(self.split_ratio, "split_ratio")
        if not 0 < s < 1:   # at 0 or 1 one view gets no light: there is no stereo pair
            raise ValueError(f"split_ratio must be in (0, 1) (at 0 or 1 one view gets no light), got {s!r}")
        for name in ("refraction_l_mm", "refraction_m_mm"):
            v = getattr(self, name)
            if v is not None:
                check_finite(v, name)
        for name in MIRROR_NAMES:
            ext = getattr(self, f"{name}_extent")
            if ext is not None and not isinstance(ext, MirrorExtent):
                raise TypeError(f"{name}_extent must be a MirrorExtent or None, got {type(ext).__name__}")
            err = getattr(self, f"{name}_error")
            if not isinstance(err, MirrorError):
                raise TypeError(f"{name}_error must be a MirrorError, got {type(err).__name__}")
        rot = self.box_rotation_rad
        if not isinstance(rot, (tuple, list)) or len(rot) != 3:
            raise ValueError(f"box_rotation_rad must be three numbers (a rotation vector), got {rot!r}")
        object.__setattr__(self, "box_rotation_rad",
                           tuple(check_finite(c, f"box_rotation_rad[{k}]") for k, c in enumerate(rot)))

    def extent(self, name: str) -> MirrorExtent | None:
        """Mirror ``name``'s (``m1`` .. ``m4``) finite rectangle, or None when it is unbounded."""
        return getattr(self, f"{name}_extent")

    def error(self, name: str) -> MirrorError:
        """Mirror ``name``'s (``m1`` .. ``m4``) pose error as built (zero for the designed pose)."""
        return getattr(self, f"{name}_error")

    @property
    def as_designed(self) -> bool:
        """True when no mirror has a pose error and the box is not turned: the paper's ideal geometry."""
        return all(self.error(n).is_zero for n in MIRROR_NAMES) and self.box_rotation_rad == (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Calibration:
    """How a rig file's values were found (``[calibration]`` in the file, written by ``psvs calibrate``):
    reprojection RMS overall and per view (px), the number of images used and their kinds (e.g.
    "16 card"), so a reader (the web UI) can say whether it works with a calibrated build."""

    rms_px: float
    rms_left_px: float
    rms_right_px: float
    images: int
    kinds: str = ""

    def __post_init__(self):
        for name in ("rms_px", "rms_left_px", "rms_right_px"):
            check_nonnegative(getattr(self, name), name, "px")
            object.__setattr__(self, name, float(getattr(self, name)))
        if not isinstance(self.images, int) or isinstance(self.images, bool) or self.images < 0:
            raise ValueError(f"images must be a whole number >= 0, got {self.images!r}")
        if not isinstance(self.kinds, str):
            raise ValueError(f"kinds must be a string, got {self.kinds!r}")


@dataclass(frozen=True)
class Rig:
    """A whole PSVS: the real camera and the mirror assembly, and how they were calibrated (None: a
    design, not measured). Make variants with :meth:`replace`."""

    camera: Camera = field(default_factory=Camera)
    mirrors: Mirrors = field(default_factory=Mirrors)
    calibration: Calibration | None = None

    def __post_init__(self):
        if not isinstance(self.camera, Camera):
            raise TypeError(f"camera must be a Camera, got {type(self.camera).__name__}")
        if not isinstance(self.mirrors, Mirrors):
            raise TypeError(f"mirrors must be a Mirrors, got {type(self.mirrors).__name__}")
        if self.calibration is not None and not isinstance(self.calibration, Calibration):
            raise TypeError(f"calibration must be a Calibration or None, got {type(self.calibration).__name__}")

    def replace(self, **changes) -> "Rig":
        """A copy with fields of the camera or the mirrors changed, e.g. ``rig.replace(plate_thickness_mm=0)``."""
        cam = {k: v for k, v in changes.items() if k in Camera.__dataclass_fields__}
        mir = {k: v for k, v in changes.items() if k in Mirrors.__dataclass_fields__}
        unknown = set(changes) - set(cam) - set(mir)
        if unknown:
            raise TypeError(f"unknown rig field(s): {', '.join(sorted(unknown))}")
        return Rig(replace(self.camera, **cam), replace(self.mirrors, **mir), self.calibration)

    def with_extents(self, extents: dict[str, MirrorExtent | None]) -> "Rig":
        """A copy with the given mirror extents (keys ``m1`` .. ``m4``)."""
        return self.replace(**{f"{k}_extent": v for k, v in extents.items()})

    def with_errors(self, errors: dict[str, MirrorError]) -> "Rig":
        """A copy with the given mirror pose errors (keys ``m1`` .. ``m4``)."""
        return self.replace(**{f"{k}_error": v for k, v in errors.items()})

    @property
    def as_designed(self) -> bool:
        """No mirror pose error and no box rotation (the lens may still distort)."""
        return self.mirrors.as_designed

    def designed_mirrors(self) -> "Rig":
        """A copy with every mirror as designed (no pose error) and the box not turned; the camera as it is."""
        return self.with_errors({n: MirrorError() for n in MIRROR_NAMES}).replace(box_rotation_rad=(0.0, 0.0, 0.0))

    @property
    def virtual_z_mm(self) -> float:
        """Z of both virtual optical centres: -(b/2) tan(omega_1), i.e. -b/2 at 45 deg (paper III.2)."""
        return -0.5 * self.mirrors.baseline_mm * math.tan(self.mirrors.angle_rad)


def default_rig() -> Rig:
    """The paper's f = 11.3 mm and b = 100 mm on a 1/2" 640x480 CCD (PULNIX TM-520), 3 mm plate."""
    return Rig()
