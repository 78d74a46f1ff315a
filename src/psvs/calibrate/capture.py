"""A capture assistant for hand-held card views: which poses are good, which are missing, and when the set
is enough to calibrate (``psvs capture``, the web UI's capture panel; docs/calibration.md).

Each frame, the card is detected in both views (:func:`detect_card`), and its pose (target -> frame C) is
estimated from the nominal rig: OpenCV's PnP on the right view, a pinhole through two mirrors, moved into
frame C (:func:`psvs.calibrate.bundle.initial_grid_pose`, the bundle adjustment's own start). A pose falls
into coverage bins of three kinds:

- **field**: the 3 x 3 cells of the image where the card's centre lands, in either view (the lens is
  calibrated where discs are seen);
- **depth**: near, mid or far third of the range (``near_mm``-``far_mm``), by the card centre's Z;
- **tilt**: the way the card faces, from its normal: flat (both turns under :data:`FLAT_MAX_RAD`), or
  left, right, up, down (turned at least :data:`TILT_MIN_RAD` toward that side of the image).

Directions are those of the image (the preview): left is toward column 0 (-X), up toward row 0 (-Y). A card
"tilted left" faces the image's left side: its right-hand edge, as the image shows it, is nearer the camera.

A view is saved once: when the card is still (its discs moved slower than ``max_speed_px_s``, by default
:data:`MAX_SPEED_PX_S`, since the previous frame's detection), and the view adds a bin not yet covered or
differs from every saved view by :data:`NEW_TURN_RAD` of orientation, :data:`NEW_DEPTH_FRACTION` of distance
or :data:`NEW_SHIFT_FRACTION` of the image's width. The set is enough when every bin is covered and
``views`` views are saved. :class:`CaptureAssistant` keeps that state over time; its
:meth:`~CaptureAssistant.step` returns a frozen record and never prints or writes (:class:`CaptureFolder`
writes).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from psvs.calibrate.bundle import GridView, initial_grid_pose
from psvs.calibrate.folder import card_view
from psvs.errors import MeasurementError
from psvs.optics.project import project_points
from psvs.optics.rig import Rig
from psvs.simulate.textures import CharucoBoard
from psvs.targets.detect import CARD_DEPTHS_MM, MIN_DISC_PX
from psvs.targets.target_points import Target, target_points_mm
from psvs.transforms import transform_from_rotvec

#: OpenCV ArUco detector's default minMarkerPerimeterRate: a marker's perimeter over the image's larger side
MIN_MARKER_PERIMETER_RATE = 0.03

FIELD_BINS = ("top-left", "top", "top-right", "left", "centre", "right", "bottom-left", "bottom", "bottom-right")
DEPTH_BINS = ("near", "mid", "far")
TILT_BINS = ("flat", "left", "right", "up", "down")
#: Every bin a complete set covers, as ``kind:name``.
ALL_BINS = tuple(f"field:{b}" for b in FIELD_BINS) + tuple(f"depth:{b}" for b in DEPTH_BINS) \
    + tuple(f"tilt:{b}" for b in TILT_BINS)

#: A tilt bin needs the card turned at least this far toward its side; flat is both turns under FLAT_MAX_RAD.
TILT_MIN_RAD = math.radians(15.0)
FLAT_MAX_RAD = math.radians(8.0)
#: A card whose discs move faster than this (px/s; 1 px a frame at 30 frames/s) is moving: not saved. A hand's
#: tremor (tenths of a mm at ~10 Hz) can exceed it on a long lens up close: rest the card, or allow more.
MAX_SPEED_PX_S = 30.0
#: A view adding no bin is still new when it differs from every saved view by one of these.
NEW_TURN_RAD = math.radians(10.0)
NEW_DEPTH_FRACTION = 0.10
NEW_SHIFT_FRACTION = 1 / 6
#: The default number of views to save, and the fewest a set may ask for (psvs calibrate needs 3).
DEFAULT_VIEWS = 20
MIN_VIEWS = 3
#: A hint is said once it has held for this many frames (no flood of flickering hints).
HINT_FRAMES = 2


@dataclass(frozen=True)
class CaptureParams:
    """How many views to save, the depth range (mm) whose thirds are the depth bins, and the fastest a card
    may move and still be saved (px/s)."""

    views: int = DEFAULT_VIEWS
    near_mm: float = 400.0
    far_mm: float = 900.0
    max_speed_px_s: float = MAX_SPEED_PX_S

    def __post_init__(self):
        if isinstance(self.views, bool) or not isinstance(self.views, int) or not MIN_VIEWS <= self.views <= 200:
            raise ValueError(f"views must be an integer {MIN_VIEWS}-200, got {self.views!r}")
        for name in ("near_mm", "far_mm"):
            v = getattr(self, name)
            if not math.isfinite(v) or v <= 0:
                raise ValueError(f"{name} must be a finite depth > 0 mm, got {v!r}")
        if self.near_mm >= self.far_mm:
            raise ValueError(f"near_mm ({self.near_mm:g}) must be < far_mm ({self.far_mm:g})")
        if not 0 < self.max_speed_px_s <= 1000 or not math.isfinite(self.max_speed_px_s):
            raise ValueError(f"max_speed_px_s must be > 0 and at most 1000 px/s, got {self.max_speed_px_s!r}")


#: A view is worth saving when at least this share of the card's points are found (with their ids certain):
#: where a card wider than its disparity has the two views' columns meet, a disc of each view may sit on
#: the other's and be lost; the rest calibrate as well.
MIN_FOUND_SHARE = 0.75


def detect_card(grey: np.ndarray, target: Target, rig: Rig) -> GridView:
    """The card's trusted discs in both views of one frame; ValueError naming what is wrong otherwise: a
    view worth saving shows the card, at least :data:`MIN_FOUND_SHARE` of its points found, each known for
    which of the card's it is (a part of a symmetric grid fits it at several places).

    The one place the capture assistant detects a target (swap in another detector here)."""
    view, det = card_view("frame", grey, target, rig)
    n = len(target_points_mm(target))
    if not det.ids_certain or len(det.ids) < MIN_FOUND_SHARE * n:
        raise ValueError(f"{len(det.ids)} of the card's {n} points found"
                         + ("" if det.ids_certain else ", not told apart for certain")
                         + ": show the whole card to both views")
    return view


@dataclass(frozen=True, eq=False)
class CardPose:
    """A detected card's pose: ``target2cam`` (4, 4) mm, its centre's depth ``distance_mm`` (Z, frame C),
    the turns of its normal toward +X (``turn_x_rad``, < 0 faces the image's left) and toward +Y
    (``turn_y_rad``, < 0 faces up), and its centre in each view ``centre_px`` {'left', 'right'}: (u, v) px."""

    target2cam: np.ndarray
    distance_mm: float
    turn_x_rad: float
    turn_y_rad: float
    centre_px: dict


def card_pose(view: GridView, rig: Rig) -> CardPose:
    """The card's pose from the right view (PnP through the rig's right virtual camera, in frame C)."""
    x = initial_grid_pose(view, rig)
    T = transform_from_rotvec(x[:3], x[3:])
    n = T[:3, 2] * (-1.0 if T[2, 2] > 0 else 1.0)          # the card's normal, toward the camera (n_z < 0)
    centre = T[:3, 3]
    px = {}
    for side in ("left", "right"):
        uv, ok = project_points(centre[None, :], rig, side)
        px[side] = (float(uv[0, 0]), float(uv[0, 1])) if ok[0] else None
    return CardPose(T, float(centre[2]), math.atan2(n[0], -n[2]), math.atan2(n[1], -n[2]), px)


def pose_bins(pose: CardPose, rig: Rig, params: CaptureParams) -> frozenset[str]:
    """The coverage bins (``kind:name``, :data:`ALL_BINS`) one pose covers."""
    w, h = rig.camera.image_size_px
    out = set()
    for uv in pose.centre_px.values():
        if uv is not None and 0 <= uv[0] < w and 0 <= uv[1] < h:
            out.add("field:" + FIELD_BINS[3 * min(int(3 * uv[1] / h), 2) + min(int(3 * uv[0] / w), 2)])
    third = (params.far_mm - params.near_mm) / 3
    k = math.floor((pose.distance_mm - params.near_mm) / third)
    if 0 <= k < 3 or pose.distance_mm == params.far_mm:
        out.add("depth:" + DEPTH_BINS[min(k, 2)])
    tx, ty = pose.turn_x_rad, pose.turn_y_rad
    if abs(tx) < FLAT_MAX_RAD and abs(ty) < FLAT_MAX_RAD:
        out.add("tilt:flat")
    for value, low, high in ((tx, "left", "right"), (ty, "up", "down")):
        if abs(value) >= TILT_MIN_RAD:
            out.add("tilt:" + (low if value < 0 else high))
    return frozenset(out)


def _differs(pose: CardPose, saved: list[CardPose], width_px: float) -> bool:
    """Whether ``pose`` differs from every saved pose by a turn, a distance or a shift in the image."""
    for other in saved:
        turn = Rotation.from_matrix(pose.target2cam[:3, :3].T @ other.target2cam[:3, :3]).magnitude()
        depth = abs(pose.distance_mm - other.distance_mm) / other.distance_mm
        a, b = pose.centre_px.get("right"), other.centre_px.get("right")
        shift = math.hypot(a[0] - b[0], a[1] - b[1]) / width_px if a and b else math.inf
        if turn < NEW_TURN_RAD and depth < NEW_DEPTH_FRACTION and shift < NEW_SHIFT_FRACTION:
            return False
    return True


def card_speed_px_s(view: GridView, last: GridView | None, dt_s: float) -> float:
    """Mean speed (px/s) of the discs both detections found, in both views; inf when it cannot be told."""
    if last is None or dt_s <= 0:
        return math.inf
    index = {tuple(np.round(p, 6)): k for k, p in enumerate(last.object_mm)}
    pairs = [(k, index[tuple(np.round(p, 6))]) for k, p in enumerate(view.object_mm) if tuple(np.round(p, 6)) in index]
    if not pairs:
        return math.inf
    a, b = np.array(pairs).T
    moved = np.concatenate([np.linalg.norm(view.left[a] - last.left[b], axis=1),
                            np.linalg.norm(view.right[a] - last.right[b], axis=1)])
    return float(np.mean(moved)) / dt_s


def check_card_visible(rig: Rig, target: Target, params: CaptureParams) -> None:
    """ValueError, before any frame is read, when the target cannot be detected over the range through this
    rig: its features (a disc's diameter; a ChArUco marker's side) at ``far_mm`` smaller than the detector
    locates (:data:`psvs.targets.detect.MIN_DISC_PX`; OpenCV's ArUco detector: a marker's perimeter at
    least :data:`MIN_MARKER_PERIMETER_RATE` of the image's larger side), both on the rig's pinhole at its
    virtual centres; or the range outside the depths the detector looks for features at
    (:data:`psvs.targets.detect.CARD_DEPTHS_MM`). A card wider than its disparity is fine: its two copies
    are separated through the rig's epipolar geometry."""
    cam, zv = rig.camera, rig.virtual_z_mm
    lo, hi = CARD_DEPTHS_MM
    if params.near_mm < lo or params.far_mm > hi:
        raise ValueError(f"the range {params.near_mm:g}-{params.far_mm:g} mm reaches outside the {lo:g}-{hi:g} mm "
                         "a card is looked for at")
    f_px = cam.focal_length_mm / max(cam.pixel_pitch_mm)
    if isinstance(target, CharucoBoard):
        size, what = target.marker_mm, "markers"
        smallest = MIN_MARKER_PERIMETER_RATE * max(cam.image_size_px) / 4
    else:
        size, what = target.diameter_mm, "discs"
        smallest = MIN_DISC_PX
    at_far = size * f_px / (params.far_mm - zv)
    if at_far < smallest:
        raise ValueError(f"the card is too small to see at the far end: its {size:g} mm {what} are {at_far:.1f} px "
                         f"across at {params.far_mm:g} mm through this rig, and the detector needs {smallest:.1f} px "
                         f"(a card with larger {what}, or a nearer far end)")


@dataclass(frozen=True, eq=False)
class CaptureStep:
    """What one frame gave: ``status`` 'no card' (``reason`` says why), 'moving', 'saved' or 'seen' (a pose
    already saved); the pose and its bins when the card was found; the card's speed (px/s, inf when it
    cannot be told); the bins a saved view added; the views saved so far; the current ``hint``, and ``said``:
    the hint to tell the user now (it changed and held :data:`HINT_FRAMES` frames), else None; whether the
    set is complete."""

    frame: int
    status: str
    reason: str = ""
    pose: CardPose | None = None
    bins: frozenset = frozenset()
    speed_px_s: float = math.inf
    new_bins: tuple = ()
    saved: int = 0
    hint: str = ""
    said: str | None = None
    complete: bool = False


class CaptureAssistant:
    """Coverage and decisions over a stream of frames (module docstring). ``step(grey, t_s)`` per frame, in
    order, with the frame's time (s)."""

    def __init__(self, target: Target, rig: Rig, params: CaptureParams = CaptureParams()):
        self.target, self.rig, self.params = target, rig, params
        self.covered: dict[str, int] = {b: 0 for b in ALL_BINS}
        self.saved: list[CardPose] = []
        self._last: tuple[GridView, float] | None = None
        self._frame = -1
        self._hint, self._held, self._said = "", 0, None

    @property
    def missing(self) -> tuple[str, ...]:
        return tuple(b for b in ALL_BINS if not self.covered[b])

    @property
    def complete(self) -> bool:
        return not self.missing and len(self.saved) >= self.params.views

    def step(self, grey: np.ndarray, t_s: float) -> CaptureStep:
        """Detect the card in one frame, judge it, and say whether to save it (``status == 'saved'``)."""
        self._frame += 1
        try:
            view = detect_card(grey, self.target, self.rig)
            pose = card_pose(view, self.rig)
        except (ValueError, cv2.error) as exc:        # no card (the detector's reason), or no pose fits it
            self._last = None
            return self._record(CaptureStep(self._frame, "no card", reason=str(exc)),
                                "show the whole card to both views")
        last, self._last = self._last, (view, t_s)
        speed = card_speed_px_s(view, last[0] if last else None, t_s - last[1] if last else 0.0)
        bins = pose_bins(pose, self.rig, self.params)
        base = dict(pose=pose, bins=bins, speed_px_s=speed)
        if speed > self.params.max_speed_px_s:
            return self._record(CaptureStep(self._frame, "moving", **base), "hold still")
        new = tuple(b for b in ALL_BINS if b in bins and not self.covered[b])
        if self.complete or not (new or (len(self.saved) < self.params.views
                                         and _differs(pose, self.saved, self.rig.camera.image_size_px[0]))):
            return self._record(CaptureStep(self._frame, "seen", **base), self._advice(pose))
        for b in bins:
            self.covered[b] += 1
        self.saved.append(pose)
        return self._record(CaptureStep(self._frame, "saved", new_bins=new, **base), self._advice(pose))

    def _record(self, step: CaptureStep, hint: str) -> CaptureStep:
        """The step with the views saved, the hint, whether to say it now, and completeness filled in."""
        self._held = self._held + 1 if hint == self._hint else 1
        self._hint = hint
        said = None
        if self._held >= HINT_FRAMES and hint != self._said:
            said = self._said = hint
        return CaptureStep(step.frame, step.status, step.reason, step.pose, step.bins, step.speed_px_s,
                           step.new_bins, len(self.saved), hint, said, self.complete)

    def _advice(self, pose: CardPose) -> str:
        """What to do next, in a card holder's words: the first missing depth, then field cell, then tilt."""
        if self.complete:
            return "enough to calibrate"
        missing = self.missing
        depth = [DEPTH_BINS.index(b[6:]) for b in missing if b.startswith("depth:")]
        if depth:
            third = (self.params.far_mm - self.params.near_mm) / 3
            k = min(depth, key=lambda j: abs(self.params.near_mm + (j + 0.5) * third - pose.distance_mm))
            lo = self.params.near_mm + k * third
            word = ("closer" if pose.distance_mm > lo + third else "farther" if pose.distance_mm < lo
                    else "hold it there")
            return f"{word} ({lo:.0f}-{lo + third:.0f} mm)"
        cells = [FIELD_BINS.index(b[6:]) for b in missing if b.startswith("field:")]
        if cells:
            return "move " + _direction(cells, pose, self.rig)
        tilts = [b[5:] for b in missing if b.startswith("tilt:")]
        if tilts:
            return "hold it flat" if tilts[0] == "flat" else f"tilt {tilts[0]}"
        return "a new pose: another distance, tilt or place"

    def describe_missing(self) -> str:
        """What the set still lacks, in words (empty when complete): e.g. '12 more view(s); the card's centre
        in the top-left, right cells of the image; a far view (733-900 mm); the card tilted up, flat'."""
        parts = []
        if len(self.saved) < self.params.views:
            parts.append(f"{self.params.views - len(self.saved)} more view(s)")
        names = {kind: [b.split(":")[1] for b in self.missing if b.startswith(kind + ":")]
                 for kind in ("field", "depth", "tilt")}
        if names["field"]:
            parts.append(f"the card's centre in the {', '.join(names['field'])} cell(s) of the image")
        third = (self.params.far_mm - self.params.near_mm) / 3
        for name in names["depth"]:
            lo = self.params.near_mm + DEPTH_BINS.index(name) * third
            parts.append(f"a {name} view ({lo:.0f}-{lo + third:.0f} mm)")
        if names["tilt"]:
            parts.append(f"the card {', '.join('flat' if t == 'flat' else 'tilted ' + t for t in names['tilt'])}")
        return "; ".join(parts)

    def require_enough(self) -> None:
        """MeasurementError 'cannot calibrate yet: ...' naming what is missing, unless the set is complete."""
        if not self.complete:
            raise MeasurementError(f"cannot calibrate yet: {len(self.saved)} view(s) saved, missing "
                                   f"{self.describe_missing()}")


def _direction(cells: list[int], pose: CardPose, rig: Rig) -> str:
    """'left', 'up', 'right and down', ...: toward the missing cell nearest to a cell the card's centres
    are in now (either view)."""
    w, h = rig.camera.image_size_px
    here = [(min(int(3 * v / h), 2), min(int(3 * u / w), 2)) for u, v in
            (uv for uv in pose.centre_px.values() if uv is not None)] or [(1, 1)]
    best = min(((c // 3, c % 3, r0, c0) for c in cells for r0, c0 in here),
               key=lambda t: abs(t[0] - t[2]) + abs(t[1] - t[3]))
    r, c, r0, c0 = best
    words = [w for w, on in (("left", c < c0), ("right", c > c0), ("up", r < r0), ("down", r > r0)) if on]
    return " and ".join(words) or "a little"


@dataclass(eq=False)
class CaptureFolder:
    """Where the saved views go: ``view_NN.png`` and the target file copied as ``target.toml``, each written
    atomically, the folder created at the first view; directly a ``psvs calibrate`` folder."""

    folder: Path
    target_text: bytes
    names: list = field(default_factory=list)

    def __post_init__(self):
        self.folder = Path(self.folder)
        check_capture_folder(self.folder)

    def save(self, grey: np.ndarray) -> str:
        """Write one view; returns its file name."""
        from psvs.io.atomic import write_atomic
        from psvs.io.images import write_png
        if not self.names:
            self.folder.mkdir(parents=True, exist_ok=True)
            write_atomic(self.folder / "target.toml", self.target_text)
        name = f"view_{len(self.names):02d}.png"
        write_png(self.folder / name, grey)
        self.names.append(name)
        return name


def check_capture_folder(folder) -> None:
    """ValueError when ``folder`` already holds a calibration folder's files (PNG images, target.toml): the
    capture would mix its views with others' or overwrite them. A file in its place is refused too."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise ValueError(f"output folder {folder} is a file")
    if folder.is_dir():
        held = sorted(p.name for p in folder.iterdir() if p.suffix.lower() == ".png" or p.name == "target.toml")
        if held:
            raise ValueError(f"output folder {folder} already holds {', '.join(held[:3])}"
                             f"{' ...' if len(held) > 3 else ''}: give a new or empty folder")


def event_lines(step: CaptureStep, name: str | None, views: int) -> list[str]:
    """What one step tells the user, one line per event (the terminal's and the web page's words): the view
    saved as ``name`` (its pose and what it added), and a new hint."""
    out = []
    if name is not None:
        p = step.pose
        tilt = f"faces {_side(p.turn_x_rad, 'left', 'right')} and {_side(p.turn_y_rad, 'up', 'down')}"
        added = "; ".join(_words(step.new_bins)) or "a new pose"
        out.append(f"frame {step.frame}: saved {name} ({step.saved}/{views}): {p.distance_mm:.0f} mm, {tilt}; "
                   f"adds {added}")
    if step.said is not None:
        out.append(f"frame {step.frame}: {step.said}")
    return out


def _words(bins) -> list[str]:
    """Bins in words, a kind at a time: 'field top, top-right', 'far', 'tilted up'."""
    names = {kind: [b.split(":")[1] for b in bins if b.startswith(kind + ":")] for kind in ("field", "depth", "tilt")}
    return ([f"field {', '.join(names['field'])}"] if names["field"] else []) + names["depth"] \
        + [("flat" if t == "flat" else f"tilted {t}") for t in names["tilt"]]


def _side(turn_rad: float, low: str, high: str) -> str:
    return f"{low if turn_rad < 0 else high} {abs(math.degrees(turn_rad)):.0f} deg"
