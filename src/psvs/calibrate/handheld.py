"""A simulated hand-held video of a calibration card: what a person shows a PSVS while the capture
assistant (:mod:`psvs.calibrate.capture`) watches.

The hand holds the card still at a series of poses (``hold_frames`` frames each) and moves it smoothly
from one to the next (``move_frames`` frames: position and orientation eased in and out, so the path and its
speed are continuous). The poses are random but purposeful, as a person following the assistant's hints
would choose them: depths stratified over the range, tilts cycling through left, right, up, down and flat
(20-32 deg, or under 4 deg flat, turned a little about the optical axis), and places spread over the 3 x 3
cells of the image. One pose in ``out_every`` holds is pushed partly out of the image. Every frame goes
through the rig's exact optics (:func:`psvs.simulate.render.render_views`) and the sensor model with fresh
noise; a moving frame is the mean of ``blur_samples`` renders over its exposure (the whole frame interval),
so a fast move smears the card as a camera's shutter does.
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from psvs.calibrate.synthetic import card_size_mm
from psvs.optics.project import project_points
from psvs.optics.rig import Rig
from psvs.simulate.scene import Pose, Scene, SceneObject
from psvs.simulate.sensor import Sensor, expose
from psvs.simulate.textures import CircleGrid, Uniform

#: A settling hand: frames, and the drift a frame (a fraction of the card's distance, sideways; ~4 px a frame).
SETTLE_FRAMES, SETTLE_FRACTION = 2, 0.004
TILTS = ("left", "right", "up", "down", "flat")
#: Euler angles (x, y, deg) of a card facing each way, times a magnitude (capture.py: ry > 0 faces left).
_TILT_SIGN = {"left": (0, 1), "right": (0, -1), "up": (-1, 0), "down": (1, 0), "flat": (0, 0)}


@dataclass(frozen=True, eq=False)
class HandFrame:
    """One frame of the path: ``kind`` 'still', 'moving' or 'out' (held partly out of the image), and the
    card's poses over its exposure (one for a still frame)."""

    kind: str
    poses: tuple


def _visible(pose: Pose, rig: Rig, local: np.ndarray, margin_px: float, apart: bool = True) -> tuple[bool, list]:
    """Whether every disc lies ``margin_px`` inside the image in both views, with ``apart`` the copies apart
    too (else they may interleave); the copies' centres (u, v) px."""
    w, h = rig.camera.image_size_px
    pts = pose.to_world(local)
    seen, centres = [], []
    for view in ("left", "right"):
        uv, ok = project_points(pts, rig, view)
        if not ok.all():
            return False, []
        inside = (uv[:, 0] > margin_px) & (uv[:, 0] < w - 1 - margin_px) & (uv[:, 1] > margin_px) \
            & (uv[:, 1] < h - 1 - margin_px)
        if not inside.all():
            return False, []
        seen.append(uv)
        centres.append(uv.mean(axis=0))
    return bool(not apart or seen[0][:, 0].min() - seen[1][:, 0].max() > margin_px), centres


def _hold_pose(rig: Rig, grid: CircleGrid, z: float, tilt: str, cell: int, rng, apart: bool = True,
               tries: int = 400) -> Pose:
    """A pose at depth ``z`` facing ``tilt`` with a copy's centre in image cell ``cell`` (0-8, row by row)
    when one of ``tries`` random places gives it; else any place showing the whole card (with ``apart``,
    its two copies apart)."""
    local = np.column_stack([grid.centres_mm(), np.zeros(grid.rows * grid.cols)])
    w, h = rig.camera.image_size_px
    margin = grid.diameter_mm * rig.camera.focal_length_mm / rig.camera.pixel_pitch_mm[0] / z
    mag = rng.uniform(20.0, 32.0) if tilt != "flat" else rng.uniform(0.0, 4.0)
    sx, sy = _TILT_SIGN[tilt]
    angles = [sx * mag + (0 if sx else rng.uniform(-4, 4)), sy * mag + (0 if sy else rng.uniform(-4, 4)),
              rng.uniform(-6.0, 6.0)]
    fallback = None
    for _ in range(tries):
        x, y = rng.uniform(-0.3, 0.3) * z, rng.uniform(-0.25, 0.25) * z
        pose = Pose.from_euler_deg([x, y, z], angles)
        ok, centres = _visible(pose, rig, local, margin, apart)
        if not ok:
            continue
        fallback = fallback or pose
        if any(min(int(3 * v / h), 2) * 3 + min(int(3 * u / w), 2) == cell for u, v in centres):
            return pose
    if fallback is None:
        raise ValueError(f"no place at {z:.0f} mm shows the whole {grid.rows}x{grid.cols} card in both views")
    return fallback


def _out_of_view(pose: Pose, rig: Rig, grid: CircleGrid) -> Pose:
    """``pose`` moved sideways until the left view's copy is cut by the image's right edge."""
    local = np.column_stack([grid.centres_mm(), np.zeros(grid.rows * grid.cols)])
    w = rig.camera.image_size_px[0]
    p = pose.position_mm.copy()
    for _ in range(400):
        p[0] += 2.0
        uv, ok = project_points(Pose(pose.rotation, p).to_world(local), rig, "left")
        reach = w - 1 + 1.5 * grid.spacing_mm * rig.camera.focal_length_mm / rig.camera.pixel_pitch_mm[0] / p[2]
        if not ok.all() or uv[:, 0].max() > reach:      # discs off the image or off the view's mirrors
            break
    return Pose(pose.rotation, p)


@dataclass(frozen=True)
class HandParams:
    """How the hand moves: each pose held ``hold_frames`` frames, joined by ``move_frames`` moving frames
    of ``blur_samples`` renders each; every ``out_every``-th hold (0: none) partly out of the image; depths
    over ``z_range_mm``. Every ``settle_every``-th hold (0: none) starts with :data:`SETTLE_FRAMES` frames of
    the card drifting slowly into place (:data:`SETTLE_FRACTION` of its distance a frame, sideways), as a
    hand settles: seen, but moving. With ``apart`` False the card's two copies may interleave (a card wider
    than its disparity, as a 5 x 7 card on a 1.6 MP camera is)."""

    hold_frames: int = 3
    move_frames: int = 2
    blur_samples: int = 3
    out_every: int = 0
    settle_every: int = 0
    z_range_mm: tuple = (400.0, 900.0)
    apart: bool = True

    def __post_init__(self):
        if self.hold_frames < 1 or self.move_frames < 0 or self.blur_samples < 1 or self.out_every < 0 \
                or self.settle_every < 0:
            raise ValueError("hold_frames and blur_samples must be >= 1, move_frames, out_every and settle_every "
                             ">= 0")


def hand_path(rig: Rig, grid: CircleGrid, holds: int, seed: int = 0, hand: HandParams = HandParams()) -> list:
    """The frames of a hand-held card's path (module docstring and :class:`HandParams`): ``holds`` poses."""
    if holds < 1:
        raise ValueError(f"holds must be >= 1, got {holds}")
    hold_frames, move_frames, blur_samples, out_every = hand.hold_frames, hand.move_frames, hand.blur_samples, \
        hand.out_every
    rng = np.random.default_rng(seed)
    edges = np.linspace(*hand.z_range_mm, 4)
    frames: list[HandFrame] = []
    previous = None
    cells, shown = rng.permutation(9), 0
    for k in range(holds):
        z = rng.uniform(edges[k % 3], edges[k % 3 + 1])
        tilt = TILTS[k % len(TILTS)]
        out = out_every and k % out_every == out_every - 1
        pose = _hold_pose(rig, grid, z, tilt, int(cells[shown % 9]), rng, hand.apart)
        shown += not out                   # a pose pushed out of view aims at no cell
        if out:
            pose = _out_of_view(pose, rig, grid)
        settle = []
        if hand.settle_every and k % hand.settle_every == hand.settle_every - 1:
            drift = SETTLE_FRACTION * pose.position_mm[2] * np.array([1.0, 0.6, 0.0])
            start = Pose(pose.rotation, pose.position_mm + SETTLE_FRAMES * drift)
            settle = _move(start, pose, SETTLE_FRAMES, blur_samples, ease=False)
        if previous is not None:
            frames += _move(previous, start if settle else pose, move_frames, blur_samples)
        frames += settle + [HandFrame("out" if out else "still", (pose,))] * hold_frames
        previous = pose
    return frames


def _move(a: Pose, b: Pose, frames: int, samples: int, ease: bool = True) -> list[HandFrame]:
    """``frames`` moving frames from ``a`` to ``b``: eased (smoothstep; else steady) position and orientation,
    each frame ``samples`` poses spread over its exposure."""
    slerp = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([a.rotation, b.rotation])))
    out = []
    for j in range(frames):
        t = (j + (np.arange(samples) + 0.5) / samples) / frames
        s = t * t * (3 - 2 * t) if ease else t
        R = slerp(s).as_matrix()
        poses = tuple(Pose(R[q], a.position_mm + s[q] * (b.position_mm - a.position_mm)) for q in range(samples))
        out.append(HandFrame("moving", poses))
    return out


def card_scene(grid: CircleGrid, pose: Pose) -> Scene:
    """The card at ``pose`` in a plain dark room (a wall 400 mm behind it), lit for its depth: one pose of a
    hand-held video."""
    from psvs.simulate.builtin import regulated_light
    z = float(pose.position_mm[2])
    return Scene((SceneObject("rectangle", pose, grid, size_mm=card_size_mm(grid)),), regulated_light(z), z + 400.0,
                 Uniform(0.08))


def render_hand_video(rig: Rig, grid: CircleGrid, path: list[HandFrame], seed: int = 0,
                      sensor: Sensor = Sensor()) -> Iterator[np.ndarray]:
    """The path's frames (H, W) uint8 through ``rig`` (supersample 1; a pose held still is rendered once,
    exposed with fresh noise, seed ``seed + k``, on every frame): a still frame is what
    ``render(card_scene(grid, pose), rig, supersample=1, sensor=sensor, seed=seed + k)`` gives, the lens's
    fall-off included (:func:`psvs.simulate.render.complex_irradiance`)."""
    from psvs.simulate.render import complex_irradiance, render_views
    cache: dict[int, np.ndarray] = {}

    def irradiance(pose: Pose) -> np.ndarray:
        if id(pose) not in cache:
            left, right = render_views(card_scene(grid, pose), rig, supersample=1)
            cache.clear()          # a path never comes back to an earlier pose object
            cache[id(pose)] = complex_irradiance(left, right, rig)
        return cache[id(pose)]

    for k, frame in enumerate(path):
        if len(frame.poses) == 1:
            e = irradiance(frame.poses[0])
        else:
            e = np.mean([irradiance(p) for p in frame.poses], axis=0)
        yield expose(e, sensor, seed + k)
