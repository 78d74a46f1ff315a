"""Rigs drawn from a seed as a user's cameras would be: the camera, the lens, the mirrors psvs designs for
them, the working range, the build as glued, the sensor's kind and the file format, the card that
calibrates it; and the calibration itself, from simulated hand-held card views written as the user's
camera would write them.

A draw is one candidate after another from the seed's own stream of random numbers
(``numpy.random.default_rng([seed, k])`` for candidate k = 0, 1, ...), the first that is physically
sensible:

1. **Geometry** (:func:`candidates`, cheap): its layout is clear, or made clear by moving M1 and M2 to the
   positions ``psvs design`` suggests (as a builder would); its working range starts where both views
   overlap, clear of the mirror box, within a hand-held card's reach; a card exists that the views can hold
   and the detector can see over the range.
2. **Calibration** (:func:`calibrated_draw`): the card views, rendered through the build and written as the
   user's files (PNG or JPEG, grey or a Bayer mosaic demosaiced by the camera), calibrate from the nominal
   design with ``psvs.calibrate.folder.calibrate_folder`` (the rig is never handed its truth) to within
   :data:`CALIBRATION_MM` over the working range, after the rigid motion no image can see (as
   tests/support/geometry.py's ``reconstruction_errors``).

A candidate that fails is *redrawn* (the next k) and the reason kept in :attr:`RigDraw.redraws`: the same
seed always gives the same draw. Only :data:`CALIBRATION_TRIES` candidates are calibrated: when all of them
miss, the last is returned as it is and the test that asserts :data:`CALIBRATION_MM` fails, printing them
(a calibration that broke must not be hidden by redrawing for ever).

What is drawn (units as in psvs: mm, px; degrees only in names ending ``_deg``):

- **Camera.** One of :data:`SENSORS` (0.3-5 MP, aspect ratios 4:3, 3:2, 5:4, 6:5, 16:10, 16:9), a pixel
  pitch of 2.2-10 um, monochrome or colour (a Bayer mosaic of any of the four phases, demosaiced by the
  camera bilinearly or edge-aware), frames saved as PNG or JPEG (quality 85-95).
- **Lens.** A stock focal length of :data:`LENSES_MM` whose horizontal half-field lies in
  :data:`HALF_FIELD_DEG`; barrel distortion plausible for that focal length (:data:`CORNER_DISTORTION`, the
  image height's relative change in the corner, OpenCV's k1, k2, k3 in the proportions of a datasheet lens)
  and a fall-off of 0-30 % in the corners (``relative_illumination``).
- **Mirrors.** b 60-160 mm, a BK7 plate 1-3 mm thick splitting 0.4-0.6, M1 at a distance the builder picks
  (12-30 mm), M2 in the middle of the clear window ``psvs design`` reports for it, or both where it
  suggests when M1's position has none (unless that puts M1 inside the lens: :data:`MIN_M1_MM`); the
  mirror sizes are the design's (``design_mirrors``) with a border of half the lens's entrance pupil
  (``--margin-mm``, the lens at f/2, f/2.8 or f/4).
- **Working range.** The disparity at the near end 28-40 % of the image's width, the far end 2-2.5 times
  the near one; the near end where the views overlap, clear of the mirror box and within a hand-held
  card's reach (:data:`MAX_NEAR_MM`), the far end at most :data:`MAX_FAR_MM`.
- **Build.** Every mirror tilted 0.05-0.3 deg about both axes (random signs) and shifted up to 0.5 mm, the
  box turned up to 0.2 deg, the lens a little off its datasheet (f 1 %, principal point 0.5 % of the
  image, k1 5 %, tangential terms 1e-3) with up to 5 % more fall-off.
- **Card.** A symmetric circle grid (5 x 7, else 4 x 6, else 4 x 5) whose discs are 2 diameters apart, at
  most :data:`MAX_SPACING_OVER_BASELINE` of the baseline, and 28 px across at the near end or less (at
  least 8 px at the far end of the card's range), held at :data:`CARD_VIEWS` poses from the near end over
  80 % of the range (``psvs.calibrate.synthetic.random_poses(..., apart=False)``: its copies may
  interleave), rendered with the renderer's 2 x 2 samples where the image is not smooth (:mod:`tests.support.adaptive`).
"""
from __future__ import annotations

import atexit
import dataclasses
import functools
import math
import shutil
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from psvs import default_rig
from psvs.calibrate.synthetic import check_card_fits
from psvs.imaging.grey import to_grey8
from psvs.io.atomic import write_atomic
from psvs.io.images import read_grey
from psvs.io.params import dumps_rig
from psvs.measure.triangulate import triangulate
from psvs.optics.design import design_mirrors
from psvs.optics.illumination import corner_rho2
from psvs.optics.project import in_image, project_points
from psvs.optics.rig import Camera, MirrorError, Mirrors, Rig
from psvs.simulate.scene import Scene
from psvs.simulate.sensor import Sensor, blur, expose
from psvs.simulate.textures import CircleGrid
from tests.reference_build import Lens, ReferenceBuild
from tests.support.geometry import whole_field_points

#: Sensor formats (width, height) px of machine-vision cameras: VGA, WVGA, IMX287, SXGA-, SXGA, IMX273,
#: 3:2 1.5 MP, full HD, WUXGA, IMX265, IMX250 (6:5), 5 MP 4:3.
SENSORS = ((640, 480), (752, 480), (720, 540), (1280, 960), (1280, 1024), (1440, 1080), (1536, 1024),
           (1920, 1080), (1920, 1200), (2048, 1536), (2448, 2048), (2592, 1944))
#: Stock C-mount focal lengths, mm.
LENSES_MM = (6.0, 8.0, 12.0, 16.0, 25.0)
#: deg: the horizontal half-field a PSVS is built for (the paper's 15.8, mv1440's 17.3).
HALF_FIELD_DEG = (9.0, 24.0)
#: The distortion in the corner (relative change of the image height, barrel < 0) of a stock lens of each
#: focal length, mm: (least, most).
CORNER_DISTORTION = {6.0: (-0.06, -0.02), 8.0: (-0.045, -0.015), 12.0: (-0.02, -0.005), 16.0: (-0.01, 0.0),
                     25.0: (-0.005, 0.003)}
#: Card views a calibration renders (docs/calibration.md asks 15-20 of a user, psvs capture saves 20). With
#: 12 or 16 the mean error over ranges reaching 1.5-2 m was 0.18-0.50 mm on some draws, 0.04-0.11 with 20.
CARD_VIEWS = 20
#: mm: the mean 3-D error, after the rigid motion no image can fix, a calibration from card views must reach.
CALIBRATION_MM = 0.1
#: The candidates one seed tries before giving up on the geometry (each a cheap check).
MAX_CANDIDATES = 50
#: The candidates one seed calibrates at most (each costs a calibration).
CALIBRATION_TRIES = 2
#: mm: the nearest M1 can sit to the camera's optical centre (the lens's front; a C-mount lens's optical
#: centre lies 10-20 mm behind it). psvs design's suggestions go down to 1 mm.
MIN_M1_MM = 12.0
#: mm: the farthest near end of a working range (a hand-held card is held over most of the range) and far end.
MAX_NEAR_MM, MAX_FAR_MM = 900.0, 2000.0
#: Megapixels of the whole sweep.
ALL_MP = (0.3, 5.1)


@dataclass(frozen=True, eq=False)
class RigDraw:
    """One drawn rig (see the module docstring). ``nominal``: the rig file a user writes (datasheet lens,
    designed mirrors, no errors); ``build``: the rig as glued, which renders the images; ``near_mm``,
    ``far_mm``: the working range; ``bayer``: None for a monochrome sensor, else the mosaic's phase
    ('RGGB', 'BGGR', 'GRBG', 'GBRG'); ``demosaic``: '' or '_EA' (OpenCV's bilinear or edge-aware);
    ``file_format``: 'png' or 'jpg'; ``card``: the circle grid; ``card_range_mm``: the depths it is held
    at; ``layout``: where the builder put M1 and M2, and why; ``margin_mm``: the border the design gave every
    mirror (``psvs design --margin-mm``); ``megapixels``: the range of sensor sizes the
    draw was restricted to; ``candidate``: k of the seed's stream; ``redraws``: why earlier candidates were
    rejected."""

    seed: int
    megapixels: tuple[float, float]
    candidate: int
    nominal: Rig
    build: Rig
    near_mm: float
    far_mm: float
    bayer: str | None
    demosaic: str
    file_format: str
    jpeg_quality: int
    card: CircleGrid
    card_range_mm: tuple[float, float]
    layout: str = ""
    margin_mm: float = 0.0
    redraws: tuple[str, ...] = ()

    @property
    def colour(self) -> bool:
        return self.bayer is not None

    @property
    def size_px(self) -> tuple[int, int]:
        return self.nominal.camera.image_size_px

    @property
    def label(self) -> str:
        """One line: seed, MP, pitch, f, b, split, plate, sensor kind, file format, range."""
        cam, m = self.nominal.camera, self.nominal.mirrors
        w, h = cam.image_size_px
        kind = f"Bayer {self.bayer}{self.demosaic}" if self.colour else "mono"
        fmt = f"jpg q{self.jpeg_quality}" if self.file_format == "jpg" else "png"
        return (f"seed {self.seed}: {w}x{h} ({w * h / 1e6:.1f} MP), {cam.pixel_pitch_mm[0] * 1e3:.2f} um, "
                f"f {cam.focal_length_mm:g} mm, b {m.baseline_mm:.0f} mm, split {m.split_ratio:.2f}, "
                f"plate {m.plate_thickness_mm:.2f} mm, {kind}, {fmt}, {self.near_mm:.0f}-{self.far_mm:.0f} mm")

    def describe(self) -> str:
        """What a failing test prints: how to replay it and both rigs as TOML files."""
        lines = [self.label, f"replay: tests.support.rig_draws.calibrated_draw({self.seed}, {self.megapixels}) "
                 f"(candidate {self.candidate} of the seed's stream)",
                 f"layout: {self.layout} (mirrors {self.margin_mm:g} mm beyond the field)",
                 f"card: {self.card} at {self.card_range_mm[0]:.0f}-{self.card_range_mm[1]:.0f} mm"]
        lines += [f"redrawn: {r}" for r in self.redraws]
        lines += ["# nominal rig (psvs design)", dumps_rig(self.nominal), "# the build (the truth)",
                  dumps_rig(self.build)]
        return "\n".join(lines)


class Rejected(Exception):
    """A candidate that is not a sensible rig; the message says why."""


def _half_field_deg(size_px, pitch_mm, f_mm) -> float:
    return math.degrees(math.atan(size_px[0] * pitch_mm / 2 / f_mm))


def _lens(rng, size_px, pitch_mm) -> tuple[float, tuple]:
    """A stock focal length whose half-field fits :data:`HALF_FIELD_DEG`, and its distortion terms."""
    fits = [f for f in LENSES_MM if HALF_FIELD_DEG[0] <= _half_field_deg(size_px, pitch_mm, f) <= HALF_FIELD_DEG[1]]
    if not fits:
        raise Rejected(f"no stock lens gives a half-field of {HALF_FIELD_DEG[0]:g}-{HALF_FIELD_DEG[1]:g} deg on "
                       f"{size_px[0]} px of {pitch_mm * 1e3:.2f} um")
    f = float(fits[rng.integers(len(fits))])
    w, h = size_px
    r2 = ((w * pitch_mm / 2) ** 2 + (h * pitch_mm / 2) ** 2) / f ** 2    # the corner's (x/z)^2 + (y/z)^2
    corner = rng.uniform(*CORNER_DISTORTION[f])
    # k1 r^2 + k2 r^4 + k3 r^6 = corner, in a datasheet lens's proportions (mv1440: -0.27, 0.12, -0.02)
    a, c = rng.uniform(0.25, 0.5), rng.uniform(0.0, 0.1)
    k1 = corner / (r2 * (1.0 - a * r2 + c * r2 * r2))
    return f, (k1, -a * k1, 0.0, 0.0, c * k1)


def _camera(rng, megapixels) -> Camera:
    sizes = [s for s in SENSORS if megapixels[0] <= s[0] * s[1] / 1e6 <= megapixels[1]]
    w, h = sizes[rng.integers(len(sizes))]
    pitch = round(float(rng.uniform(2.2, 10.0)), 2) * 1e-3
    f, dist = _lens(rng, (w, h), pitch)
    cam = Camera(focal_length_mm=f, pixel_pitch_mm=(pitch, pitch), image_size_px=(w, h),
                 principal_point_px=((w - 1) / 2, (h - 1) / 2), distortion=dist)
    falloff = rng.uniform(0.0, 0.3)
    return replace(cam, relative_illumination=(-falloff / corner_rho2(cam), 0.0))


def _designed(rng, cam: Camera) -> tuple[Rig, str, float]:
    """The nominal rig with a clear layout and the design's mirror sizes, what the builder did, the margin."""
    b = round(float(rng.uniform(60.0, 160.0)))
    c1 = round(float(rng.uniform(12.0, 30.0)), 1)
    mirrors = Mirrors(baseline_mm=float(b), m1_axis_distance_mm=c1, m2_axis_distance_mm=2 * c1,
                      plate_thickness_mm=round(float(rng.uniform(1.0, 3.0)), 2), refractive_index=1.5168,
                      split_ratio=round(float(rng.uniform(0.4, 0.6)), 2))
    rig = Rig(cam, mirrors)
    # every mirror a border of half the lens's entrance pupil wider (psvs design --margin-mm), at f/2-f/4
    margin = round(cam.focal_length_mm / (2 * float(rng.choice([2.0, 2.8, 4.0]))), 2)
    d = design_mirrors(rig, margin_mm=margin)
    if d.m2_window_mm is not None:
        c2 = round(0.5 * sum(d.m2_window_mm), 2)
        note = (f"M1 at {c1:g} mm, M2 at {c2:g} mm: the middle of its clear window {d.m2_window_mm[0]:.2f}-"
                f"{d.m2_window_mm[1]:.2f} mm")
    elif d.suggestion_mm is not None:
        s1, c2 = (round(v, 2) for v in d.suggestion_mm)
        if s1 < MIN_M1_MM:
            raise Rejected(f"M1 at {c1:g} mm has no clear M2 and psvs design suggests M1 at {s1:g} mm, inside the "
                           f"lens (M1 must lie {MIN_M1_MM:g} mm or more ahead of its optical centre)")
        note = f"M1 at {c1:g} mm had no clear M2: moved to the suggested M1 {s1:g} mm, M2 {c2:g} mm"
        c1 = s1
    else:
        raise Rejected(f"no clear layout for b {b} mm, M1 {c1} mm ({d.problems[:1] or d.search_note})")
    d = design_mirrors(rig.replace(m1_axis_distance_mm=c1, m2_axis_distance_mm=c2), margin_mm=margin, search=False)
    if not d.ok:
        raise Rejected(f"the layout psvs chose is blocked: {d.problems}")
    return d.rig, note, margin


def _working_range(rng, rig: Rig) -> tuple[float, float]:
    cam, b, zv = rig.camera, rig.mirrors.baseline_mm, rig.virtual_z_mm
    w = cam.image_size_px[0]
    d_near = rng.uniform(0.28, 0.40) * w
    near = zv + b * cam.focal_length_mm / (cam.pixel_pitch_mm[0] * d_near)
    from psvs.optics.design import working_range
    from psvs.simulate.render import rig_front_z_mm
    overlap = working_range(rig, 1.0, 2.0).overlap_start_mm
    front = rig_front_z_mm(rig)
    if near < max(1.5 * overlap, 2.0 * front, 250.0):
        raise Rejected(f"the near end {near:.0f} mm lies too close: the views overlap from {overlap:.0f} mm, the "
                       f"mirrors end at {front:.0f} mm")
    if near > MAX_NEAR_MM:
        raise Rejected(f"the near end {near:.0f} mm lies beyond a hand-held card's reach ({MAX_NEAR_MM:g} mm)")
    near = round(near, -1)
    return near, min(round(near * rng.uniform(2.0, 2.5), -1), MAX_FAR_MM)


#: The card's disc spacing, at most, over the baseline: the detector pairs a disc with its twin along the
#: row, which must lie well beyond the disc's neighbours (docs/calibration.md; the shipped rigs' cards: 0.14,
#: 0.16). At 0.29 every view of a 5 x 7 card (b 79 mm, 22.7 mm spacing) was refused: its two copies' discs
#: fell on each other or were labelled uncertainly.
MAX_SPACING_OVER_BASELINE = 0.16
#: px: the smallest disc diameter at the far end of the card's range, and the largest at the near end.
CARD_DISC_PX = (8.0, 28.0)


def _card(rig: Rig, z_range) -> CircleGrid:
    """A circle grid sized for the rig (module docstring), or Rejected."""
    cam, zv = rig.camera, rig.virtual_z_mm
    px_per_mm = lambda z: cam.focal_length_mm / (cam.pixel_pitch_mm[0] * (z - zv))  # noqa: E731
    d = round(min(CARD_DISC_PX[1] / px_per_mm(z_range[0]),
                  MAX_SPACING_OVER_BASELINE * rig.mirrors.baseline_mm / 2.0), 1)
    why = ""
    for scale in (1.0, 0.85, 0.7):
        dd = round(d * scale, 1)
        if dd * px_per_mm(z_range[1]) < CARD_DISC_PX[0]:
            why = why or (f"discs of {dd:g} mm (spaced at most {MAX_SPACING_OVER_BASELINE:g} b) are under "
                          f"{CARD_DISC_PX[0]:g} px at {z_range[1]:g} mm")
            break
        for rows, cols in ((5, 7), (4, 6), (4, 5)):
            card = CircleGrid(rows, cols, round(2.0 * dd, 1), dd)
            try:
                check_card_fits(rig, card, CARD_VIEWS, z_range, apart=False)
            except ValueError as exc:
                why = str(exc)
                continue
            return card
    raise Rejected(f"no card fits: {why}")


def _build(rng, nominal: Rig) -> Rig:
    cam = nominal.camera
    w, h = cam.image_size_px
    k1, k2, _, _, k3 = cam.distortion
    a2, _ = cam.relative_illumination
    lens = replace(cam, focal_length_mm=cam.focal_length_mm * (1 + rng.uniform(-0.01, 0.01)),
                   principal_point_px=(cam.principal_point_px[0] + rng.uniform(-0.005, 0.005) * w,
                                       cam.principal_point_px[1] + rng.uniform(-0.005, 0.005) * h),
                   distortion=(k1 * (1 + rng.uniform(-0.05, 0.05)), k2 * (1 + rng.uniform(-0.1, 0.1)),
                               rng.uniform(-1e-3, 1e-3), rng.uniform(-1e-3, 1e-3), k3),
                   relative_illumination=(a2 - rng.uniform(0.0, 0.05) / corner_rho2(cam), 0.0))
    errors = {}
    for name in ("m1", "m2", "m3", "m4"):
        tilt = np.radians(rng.uniform(0.05, 0.3, 2) * rng.choice([-1.0, 1.0], 2))
        errors[name] = MirrorError((float(tilt[0]), float(tilt[1])), float(rng.uniform(-0.5, 0.5)))
    box = tuple(float(v) for v in np.radians(rng.uniform(-0.2, 0.2, 3)))
    build = Rig(lens, replace(nominal.mirrors, box_rotation_rad=box))
    return build.with_errors(errors)


def _candidate(seed: int, k: int, megapixels) -> RigDraw:
    rng = np.random.default_rng([seed, k])
    cam = _camera(rng, megapixels)
    nominal, layout, margin = _designed(rng, cam)
    near, far = _working_range(rng, nominal)
    card_range = (near, round(near + 0.8 * (far - near), -1))
    card = _card(nominal, card_range)
    build = _build(rng, nominal)
    bayer = None if rng.random() < 0.5 else ("RGGB", "BGGR", "GRBG", "GBRG")[rng.integers(4)]
    demosaic = "" if bayer is None or rng.random() < 0.5 else "_EA"
    fmt = "png" if rng.random() < 0.5 else "jpg"
    quality = int(rng.integers(85, 96))
    return RigDraw(seed, tuple(megapixels), k, nominal, build, near, far, bayer, demosaic, fmt, quality, card,
                   card_range, layout, margin)


def candidates(seed: int, megapixels: tuple[float, float] = ALL_MP):
    """The seed's geometrically sensible candidates in order (module docstring, step 1), each with the
    reasons the candidates before it were rejected."""
    why = []
    for k in range(MAX_CANDIDATES):
        try:
            draw = _candidate(seed, k, megapixels)
        except Rejected as exc:
            why.append(f"candidate {k}: {exc}")
            continue
        yield dataclasses.replace(draw, redraws=tuple(why))
        why.append(f"candidate {k}: not calibrated to {CALIBRATION_MM} mm (see its calibration)")
    raise RuntimeError(f"seed {seed}: no sensible rig in {MAX_CANDIDATES} candidates:\n" + "\n".join(why))


def draw_rig(seed: int, megapixels: tuple[float, float] = ALL_MP) -> RigDraw:
    """The rig of ``seed`` (module docstring), with sensors of ``megapixels`` (min, max) MP only: the
    draw :func:`calibrated_draw` settles on (it is calibrated, once per session)."""
    return calibrated_draw(seed, tuple(megapixels)).draw


# --- the user's camera: frames as files ------------------------------------------------------------------

#: Relative sensitivity of a colour sensor's red, green and blue sites (a white-balanced camera applies
#: the inverse as gain, so a grey scene stays grey and red and blue carry more noise).
BAYER_QE = {"R": 0.55, "G": 1.0, "B": 0.45}


def camera_frame(irradiance: np.ndarray, draw: RigDraw, seed: int, sensor: Sensor = Sensor()) -> np.ndarray:
    """What the draw's camera delivers for a noiseless irradiance (H, W) (1.0 = full well, the renderer's
    ``RenderResult.irradiance``): monochrome (H, W) uint8 through ``sensor``
    (``psvs.simulate.sensor.expose``); colour (H, W, 3) uint8 BGR: the optics' blur, then each site of the
    Bayer mosaic exposed as ``expose`` does with its colour's sensitivity (:data:`BAYER_QE`: its full well
    that share, so its shot and read noise are larger), white-balanced (the grey level is ``expose``'s), and
    the mosaic demosaiced by OpenCV (``cv2.COLOR_Bayer<phase>2BGR[_EA]``)."""
    if not draw.colour:
        return expose(irradiance, sensor, seed)
    rng = np.random.default_rng(seed)
    electrons = np.clip(blur(np.asarray(irradiance, dtype=np.float64), sensor.blur_sigma_px), 0, None)
    electrons *= sensor.full_well_e
    raw = np.empty(electrons.shape, np.uint8)
    for i, colour in enumerate(draw.bayer):
        site = (slice(i // 2, None, 2), slice(i % 2, None, 2))
        full_well = sensor.full_well_e * BAYER_QE[colour]
        e = electrons[site] * BAYER_QE[colour]
        if sensor.shot_noise:
            e = rng.poisson(e).astype(np.float64)
        if sensor.read_noise_e > 0:
            e = e + rng.normal(0.0, sensor.read_noise_e, e.shape)
        raw[site] = to_grey8(sensor.gain * 255.0 * e / full_well)
    return cv2.cvtColor(raw, getattr(cv2, f"COLOR_Bayer{draw.bayer}2BGR{draw.demosaic}"))


def save_frame(path, frame: np.ndarray, draw: RigDraw) -> Path:
    """Write a camera frame as the draw's file format (PNG, or JPEG at its quality), atomically; the path
    with the format's suffix."""
    path = Path(path).with_suffix("." + draw.file_format)
    params = [cv2.IMWRITE_JPEG_QUALITY, draw.jpeg_quality] if draw.file_format == "jpg" else []
    ok, buf = cv2.imencode("." + draw.file_format, frame, params)
    assert ok, path
    write_atomic(path, buf.tobytes())
    return path


def read_frame(path, draw: RigDraw) -> np.ndarray:
    """A frame file as psvs reads every image: (H, W) uint8 grey (luma of a colour file), checked against
    the camera's size (``psvs.io.images.read_grey``)."""
    return read_grey(path, expect_size=draw.size_px)


# --- calibration from hand-held card views ---------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class DrawCalibration:
    """A draw calibrated from its card views: the draw, the folder (its card files and target.toml), the
    result of ``calibrate_folder``, the 3-D errors over the working range before and after the best rigid
    motion (mm, (N,) each: :func:`reconstruction_errors`), the seconds each stage took, and the calibrations
    of the candidates rejected before it (``(RigDraw, why)``)."""

    draw: RigDraw
    folder: Path
    result: object
    raw_mm: np.ndarray
    aligned_mm: np.ndarray
    seconds: dict
    rejected: tuple = ()

    @property
    def rig(self) -> Rig:
        """The calibrated rig (what the user's rig file holds after ``psvs calibrate``)."""
        return self.result.rig

    @property
    def error_mm(self) -> float:
        """Mean 3-D error after the rigid motion, mm (inf when a point was not triangulated)."""
        return float(np.mean(self.aligned_mm))

    @property
    def untriangulated(self) -> int:
        """Points of the check the calibrated rig could not triangulate."""
        return int(np.sum(~np.isfinite(self.aligned_mm)))

    @property
    def ok(self) -> bool:
        return self.error_mm <= CALIBRATION_MM

    def describe(self) -> str:
        """The draw and its calibration, as a failing test prints it."""
        r = self.result
        lines = [f"calibration: {len(r.used)} views used, {len(r.skipped)} skipped, RMS {r.bundle.rms_px:.3f} px, "
                 f"mean 3-D error {self.error_mm:.3f} mm after the rigid motion ({self.untriangulated} of "
                 f"{len(self.aligned_mm)} points not triangulated), {np.mean(self.raw_mm):.2f} mm before"]
        lines += [f"  skipped {k}: {v}" for k, v in sorted(r.skipped.items())]
        lines += [f"rejected candidate {d.candidate} ({d.label}): {why}" for d, why in self.rejected]
        return "\n".join(lines) + "\n" + self.draw.describe()


_ROOT = None


def scratch(name: str) -> Path:
    """A folder for the session's files (one temporary root per process, removed when the process ends: a
    run of the suite left a psvs-sweep-* folder of card views in TMPDIR every time)."""
    global _ROOT
    if _ROOT is None:
        _ROOT = Path(tempfile.mkdtemp(prefix="psvs-sweep-"))
        atexit.register(shutil.rmtree, _ROOT, True)
    path = _ROOT / name
    path.mkdir(parents=True, exist_ok=True)
    return path


def reconstruction_errors(calibrated: Rig, draw: RigDraw, n_side: int = 9, depths: int = 5):
    """Triangulate the true correspondences of points over the draw's common field and working range
    (``n_side`` x ``n_side`` at ``depths`` depths, tests/support/geometry.py's :func:`whole_field_points`) with a
    calibrated rig (exact model), as tests/support/geometry.py's :func:`reconstruction_errors` does for 400-1200 mm:
    (errors (N,) mm, errors after the best rigid motion (N,) mm, the points (N, 3)). A point both views of the
    build see on the sensor but the calibrated rig cannot triangulate (its mirrors' extents or its lens put
    the correspondence outside its model) has an infinite error in both."""
    from tests.support.geometry import kabsch
    pts = whole_field_points(draw.nominal, n_side=n_side, depths=tuple(np.linspace(draw.near_mm, draw.far_mm, depths)))
    left, okl = project_points(pts, draw.build, "left")
    right, okr = project_points(pts, draw.build, "right")
    seen = okl & okr & in_image(left, draw.build) & in_image(right, draw.build)
    tri = triangulate(left[seen], right[seen], calibrated, model="exact")
    pts, got, ok = pts[seen], tri.points_mm, tri.valid
    raw, aligned = np.full(len(pts), np.inf), np.full(len(pts), np.inf)
    raw[ok] = np.linalg.norm(got[ok] - pts[ok], axis=1)
    R, t = kabsch(got[ok], pts[ok])
    aligned[ok] = np.linalg.norm(got[ok] @ R.T + t - pts[ok], axis=1)
    return raw, aligned, pts


def card_scene(draw: RigDraw, pose) -> Scene:
    """psvs.calibrate.synthetic's card scene (``render_grid_shots``): the draw's card held at ``pose`` on a dark
    backdrop 400 mm behind it, the regulated light."""
    from psvs.calibrate.synthetic import card_size_mm
    from psvs.simulate.builtin import regulated_light
    from psvs.simulate.scene import SceneObject
    from psvs.simulate.textures import Uniform
    z = float(pose.position_mm[2])
    card = SceneObject("rectangle", pose, draw.card, size_mm=card_size_mm(draw.card))
    return Scene((card,), regulated_light(z), z + 400.0, Uniform(0.08))


def render_card_views(draw: RigDraw, folder: Path, views: int = CARD_VIEWS) -> list[Path]:
    """The card at ``views`` hand-held poses (``random_poses(..., apart=False)``) through the build, rendered
    adaptively (:func:`tests.support.adaptive.render_irradiance`), exposed by the draw's camera and saved as its
    files in ``folder`` with the card's target.toml; the paths."""
    from psvs.calibrate.synthetic import random_poses
    from psvs.targets.target_file import dumps_target
    from tests.support.adaptive import render_irradiance
    seed = 1000 * draw.seed + draw.candidate
    poses = random_poses(draw.build, draw.card, views, seed=seed, z_range_mm=draw.card_range_mm, apart=False)
    paths = []
    for k, pose in enumerate(poses):
        irradiance, _ = render_irradiance(card_scene(draw, pose), draw.build, adaptive=True)
        paths.append(save_frame(folder / f"card_{k:02d}", camera_frame(irradiance, draw, seed=seed + 7919 * k), draw))
    (folder / "target.toml").write_text(dumps_target(draw.card))
    return paths


def calibrate_candidate(draw: RigDraw, views: int = CARD_VIEWS) -> DrawCalibration:
    """Render the candidate's card views, write them as its camera's files and calibrate from its nominal
    rig (``calibrate_folder``), then measure against its build."""
    from psvs.calibrate.folder import calibrate_folder
    folder = scratch(f"cards-{draw.seed}-{draw.megapixels[0]:g}-{draw.megapixels[1]:g}-{draw.candidate}-{views}")
    t0 = time.perf_counter()
    render_card_views(draw, folder, views)
    t1 = time.perf_counter()
    res = calibrate_folder(folder, draw.nominal)
    t2 = time.perf_counter()
    raw, aligned, _ = reconstruction_errors(res.rig, draw)
    return DrawCalibration(draw, folder, res, raw, aligned, {"card views": t1 - t0, "calibration": t2 - t1})


@functools.lru_cache(maxsize=None)
def calibrated_draw(seed: int, megapixels: tuple[float, float] = ALL_MP) -> DrawCalibration:
    """The draw of ``seed`` calibrated from its card views as a user would (module docstring, step 2): the
    first of the seed's :func:`candidates` whose calibration reaches :data:`CALIBRATION_MM`, or the last of
    :data:`CALIBRATION_TRIES` tried; cached per test session. A candidate no card pose shows, or whose views
    do not calibrate at all (``calibrate_folder`` refuses them), counts as one that misses; when the last
    one does, AssertionError with its description."""
    rejected = []
    for k, draw in enumerate(candidates(seed, tuple(megapixels))):
        last = k + 1 == CALIBRATION_TRIES
        try:
            cal = calibrate_candidate(draw)
        except ValueError as exc:
            if last:
                raise AssertionError(f"the card views do not calibrate: {exc}\n{draw.describe()}") from exc
            rejected.append((draw, f"the card views do not calibrate: {exc}"))
            continue
        if cal.ok or last:
            return dataclasses.replace(cal, rejected=tuple(rejected))
        rejected.append((draw, f"calibrated to {cal.error_mm:.3f} mm ({cal.untriangulated} points not "
                               f"triangulated)"))
    raise AssertionError("unreachable")


#: random_build's lens distortion (OpenCV's k1, k2, p1, p2, k3)
DIST = (-0.2, 0.08, 1.5e-3, -1.0e-3, -0.02)


def random_build(seed: int, tilt_deg=(0.1, 0.3), shift_mm=0.8, box_deg=0.3):
    """A rig and its reference twin with every mirror tilted 0.1-0.3 deg about both axes (random signs),
    shifted up to 0.8 mm, the box turned up to 0.3 deg, f 1 % and the principal point 5 px off."""
    rng = np.random.default_rng(seed)
    errors = {}
    for name in ("m1", "m2", "m3", "m4"):
        a, b = np.radians(rng.uniform(*tilt_deg, 2) * rng.choice([-1, 1], 2))
        errors[name] = (float(a), float(b), float(rng.uniform(-shift_mm, shift_mm)))
    box = np.radians(rng.uniform(-box_deg, box_deg, 3))
    f, cx, cy = 11.3 * 1.01, 319.5 + 5.0, 239.5 - 4.0
    rig = default_rig().replace(focal_length_mm=f, principal_point_px=(cx, cy), distortion=DIST,
                                box_rotation_rad=tuple(box))
    rig = rig.with_errors({k: MirrorError(v[:2], v[2]) for k, v in errors.items()})
    ref = ReferenceBuild(Lens(f=f, centre=(cx, cy), dist=DIST), errors=errors, box_rotvec=box)
    return rig, ref
