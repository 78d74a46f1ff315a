"""Physical bounds on the values of a rig file: what a real lens, sensor, plate and build have.

A rig file is a measurement of hardware, so a value far outside what hardware can have is a typo or a
unit slip (metres for mm, radians for degrees), never a rig: a principal point of 1e12 px, a mirror tilted
89 deg or a 200000 x 200000 px sensor would otherwise be accepted and a command would then run for minutes
or answer nonsense. :func:`check_rig_bounds` refuses such a rig in one line naming the file's key, the
value and the bound. The bounds are generous (a builder's extreme, not a typical rig) and finite; they
contain everything ``psvs calibrate`` can write (its solver keeps |k| <= 2, |p| <= 0.2, tilts and the box
within +-0.1 rad, shifts within +-20 mm).

They apply to rig *files* (:func:`psvs.io.params.rig_from_dict` and the writer), not to the
:class:`~psvs.optics.rig.Rig` dataclasses: code makes rigs a file never holds (a sensor window's camera
has its principal point outside the window). docs/rig_file.md lists them; :data:`BOUNDS` is that table.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from psvs import _budget
from psvs.optics.illumination import corner_rho2, ri_range
from psvs.optics.plate import file_refraction_terms, plausible_refraction_terms
from psvs.optics.rig import MIRROR_NAMES, Rig


@dataclass(frozen=True)
class Bound:
    """``lo <= value <= hi`` for the file key ``key`` (in the file's unit ``unit``); ``what`` says what
    the range is, for the message (e.g. "what lenses have")."""

    key: str
    lo: float
    hi: float
    unit: str
    what: str

    def check(self, value: float, name: str | None = None) -> None:
        """ValueError "<name> = <value> <unit> is outside <what> (<lo>..<hi> <unit>)" unless lo <= value <= hi."""
        if not self.lo <= value <= self.hi:
            unit = f" {self.unit}" if self.unit else ""
            raise ValueError(f"{name or self.key} = {value:.12g}{unit} is outside {self.what} ({self.range})")

    @property
    def range(self) -> str:
        """The range as the messages and docs/rig_file.md write it, e.g. ``0.5..2000 mm``."""
        return f"{self.lo:.12g}..{self.hi:.12g}" + (f" {self.unit}" if self.unit else "")


#: Bytes one frame of the camera costs a command that holds it, per pixel: eight float64 planes (the image,
#: its float copy, filtered and gradient images, edge and label maps), the least a command processing a
#: frame holds at once. A camera whose frame needs more than the usable memory cannot be used on this
#: machine, so its rig is refused when loaded.
FRAME_BYTES_PER_PX = 64

#: The bounds, one per key (``[k]`` entries and the four mirrors share theirs). Lengths mm, angles deg.
BOUNDS = (
    Bound("camera.focal_length_mm", 0.5, 2000.0, "mm", "what lenses have"),
    Bound("camera.pixel_pitch_mm", 0.0005, 0.1, "mm", "what sensors have"),
    Bound("camera.image_size_px", 16, 65536, "px", "what sensors have"),
    Bound("camera.image_size_px (pixels)", 0, 2 ** 28, "px", "what sensors have"),
    Bound("camera.principal_point_px", -0.5, math.inf, "px", "the sensor"),   # hi: W - 0.5, H - 0.5
    Bound("camera.distortion (k1, k2, k3)", -3.0, 3.0, "", "what lenses have"),
    Bound("camera.distortion (p1, p2)", -0.3, 0.3, "", "what lenses have"),
    Bound("camera.relative_illumination (a2, a4)", -50.0, 50.0, "", "what lenses have"),
    Bound("camera.relative_illumination (RI over the sensor)", 0.05, 1.0, "", "what lenses pass"),
    Bound("mirrors.baseline_mm", 5.0, 1000.0, "mm", "a mirror rig's size"),
    Bound("mirrors.m1_axis_distance_mm", 1.0, 1000.0, "mm", "a mirror rig's size"),
    Bound("mirrors.m2_axis_distance_mm", 1.0, 1000.0, "mm", "a mirror rig's size"),
    Bound("mirrors.angle_deg", 20.0, 70.0, "deg", "what a mirror rig is built with"),
    Bound("mirrors.plate_thickness_mm", 0.0, 30.0, "mm", "what beam-splitter plates have"),
    Bound("mirrors.refractive_index", 1.0, 2.5, "", "what glasses have"),
    Bound("mirrors.refraction_l_mm", -100.0, 100.0, "mm", "three times what a 30 mm plate gives"),
    Bound("mirrors.refraction_m_mm", -100.0, 100.0, "mm", "three times what a 30 mm plate gives"),
    Bound("mirrors.box_rotation_deg", -6.0, 6.0, "deg", "a build's errors"),
    Bound("mirrors.mN.tilt_deg", -6.0, 6.0, "deg", "a build's errors"),
    Bound("mirrors.mN.shift_mm", -25.0, 25.0, "mm", "a build's errors"),
    Bound("mirrors.mN.along_mm, height_mm", -10000.0, 10000.0, "mm", "a mirror rig's size"),
)
_BY_KEY = {b.key: b for b in BOUNDS}


def bound(key: str) -> Bound:
    """The :class:`Bound` of a key of :data:`BOUNDS`."""
    return _BY_KEY[key]


def check_rig_bounds(rig: Rig, lens_key: str = "distortion", memory: bool = True) -> None:
    """ValueError naming the file's key, the value and the bound for the first value of ``rig`` outside
    :data:`BOUNDS` (angles compared in degrees, as the file holds them); with ``memory``, also when one
    frame of its camera (:data:`FRAME_BYTES_PER_PX`) needs more than the usable memory.

    ``lens_key`` is the file's key for the lens terms (``distortion``, or an older file's ``distortion_k``).
    """
    _check_camera(rig, lens_key, memory)
    _check_mirrors(rig)


def _check_camera(rig: Rig, lens_key: str, memory: bool) -> None:
    c = rig.camera
    bound("camera.focal_length_mm").check(c.focal_length_mm)
    for k, p in enumerate(c.pixel_pitch_mm):
        bound("camera.pixel_pitch_mm").check(p, f"camera.pixel_pitch_mm[{k}]")
    for k, n in enumerate(c.image_size_px):
        bound("camera.image_size_px").check(n, f"camera.image_size_px[{k}]")
    w, h = c.image_size_px
    total = bound("camera.image_size_px (pixels)")
    if w * h > total.hi:
        raise ValueError(f"camera.image_size_px = [{w}, {h}] is {w * h} px, outside {total.what} "
                         f"(at most {total.hi} px)")
    if memory:
        _budget.check_memory(FRAME_BYTES_PER_PX * w * h, f"camera.image_size_px = [{w}, {h}] ({w * h} px, "
                             f"{FRAME_BYTES_PER_PX} B a pixel for one frame)")
    for k, (p, n) in enumerate(zip(c.principal_point_px, (w, h), strict=True)):
        Bound("camera.principal_point_px", -0.5, n - 0.5, "px", "the sensor").check(
            p, f"camera.principal_point_px[{k}]")
    radial, tangential = bound("camera.distortion (k1, k2, k3)"), bound("camera.distortion (p1, p2)")
    for k, (name, value) in enumerate(zip(("k1", "k2", "p1", "p2", "k3"), c.distortion, strict=True)):
        (radial if name.startswith("k") else tangential).check(value, f"camera.{lens_key}[{k}] ({name})")
    _check_illumination(c)


def _check_illumination(c) -> None:
    """Each term within its bound, then RI over the whole sensor (axis to farthest corner) within what a lens
    passes: never more light off the axis than on it, and at least 5 % in the corners."""
    for k, (name, value) in enumerate(zip(("a2", "a4"), c.relative_illumination, strict=True)):
        bound("camera.relative_illumination (a2, a4)").check(value, f"camera.relative_illumination[{k}] ({name})")
    ri = bound("camera.relative_illumination (RI over the sensor)")
    lo, hi = ri_range(c)
    if lo < ri.lo or hi > ri.hi + 1e-12:
        a2, a4 = c.relative_illumination
        bad = lo if lo < ri.lo else hi
        raise ValueError(f"camera.relative_illumination = [{a2:.12g}, {a4:.12g}] gives RI = {bad:.3g} on the "
                         f"sensor (1 + a2 rho^2 + a4 rho^4 up to its corner, rho = {corner_rho2(c) ** 0.5:.3g}), "
                         f"outside {ri.what} ({ri.range})")


def _deg(rad: float) -> float:
    """Degrees as a file holds them (12 significant digits, as psvs writes them): a file's 6 deg, read as
    radians, compares as 6, not 6.000000000000001."""
    return float(f"{math.degrees(rad):.12g}")


def _check_refraction_terms(rig: Rig) -> None:
    """ValueError when a file's l or m of eq. (15) lies beyond :func:`psvs.optics.plate.file_refraction_terms`
    (what a plate of its kind gives, widened by that range's width): no plate's terms (a decimal slip, l = 20 for
    a 3 mm plate's 1.8, put every depth 12 % off)."""
    m = rig.mirrors
    for key, (lo, hi), (f_lo, f_hi) in zip(("refraction_l_mm", "refraction_m_mm"), plausible_refraction_terms(rig),
                                           file_refraction_terms(rig), strict=True):
        value = getattr(m, key)
        if value is not None and not f_lo <= value <= f_hi:
            raise ValueError(f"mirrors.{key} = {value:g} mm is no plate's: a plate of {m.plate_thickness_mm:g} mm "
                             f"(n {m.refractive_index:g}) gives {lo:.3g}-{hi:.3g} mm (fit-refraction's range; a file "
                             f"may hold {f_lo:.3g}-{f_hi:.3g} mm)")


def _check_mirrors(rig: Rig) -> None:
    m = rig.mirrors
    for key in ("baseline_mm", "m1_axis_distance_mm", "m2_axis_distance_mm", "plate_thickness_mm",
                "refractive_index"):
        bound(f"mirrors.{key}").check(getattr(m, key))
    bound("mirrors.angle_deg").check(_deg(m.angle_rad))
    for key in ("refraction_l_mm", "refraction_m_mm"):
        if getattr(m, key) is not None:
            bound(f"mirrors.{key}").check(getattr(m, key))
    _check_refraction_terms(rig)
    for k, r in enumerate(m.box_rotation_rad):
        bound("mirrors.box_rotation_deg").check(_deg(r), f"mirrors.box_rotation_deg[{k}]")
    for name in MIRROR_NAMES:
        err, ext = m.error(name), m.extent(name)
        for k, t in enumerate(err.tilt_rad):
            bound("mirrors.mN.tilt_deg").check(_deg(t), f"mirrors.{name}.tilt_deg[{k}]")
        bound("mirrors.mN.shift_mm").check(err.shift_mm, f"mirrors.{name}.shift_mm")
        if ext is not None:
            for key, pair in (("along_mm", ext.along_mm), ("height_mm", ext.height_mm)):
                for k, v in enumerate(pair):
                    bound("mirrors.mN.along_mm, height_mm").check(v, f"mirrors.{name}.{key}[{k}]")
