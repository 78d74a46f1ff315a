"""Frames and videos the tests of several packages share."""
import dataclasses
import hashlib
from pathlib import Path

import cv2
import numpy as np

from psvs.io.params import load_rig
from psvs.live.simulated import SimulatedSequence, disc_scene, ping_pong_positions
from psvs.simulate.sensor import expose
from tests.support.scenes import rim_seed

FRAMES = 5


def write_frames(folder: Path, rig_name: str, bits: int):
    """A disc moving 50 mm in depth over three positions, ``FRAMES`` frames exposed at ``bits`` bits:
    ``video/`` holds them as psvs reads files (8-bit, or 12-bit values in 16-bit PNGs) and ``served/`` as
    the emulator reads them. Returns (video folder, served folder, seed)."""
    rig = load_rig(rig_name)
    scene = disc_scene(z_mm=700.0, radius_mm=30.0, x_mm=15.0, y_mm=-20.0)
    positions = ping_pong_positions(FRAMES, [-10.0, 6.0, -50.0], 3)
    seq = SimulatedSequence(scene, rig, positions, seed=7)
    video, served = folder / "video", folder / "served"
    video.mkdir(parents=True)
    served.mkdir()
    for k in range(FRAMES):
        img = expose(seq.irradiance(k), seq.sensor, 7 + k, bits=bits)
        if bits == 12:
            assert 2048 <= img.max() <= 4095       # a 12-bit frame (psvs finds a file's depth from its top)
        cv2.imwrite(str(video / f"f{k:03d}.png"), img)
        cv2.imwrite(str(served / f"f{k:03d}.png"), img if bits == 8 else (img.astype(np.uint16) << 4))
    u, v = rim_seed(rig, scene, positions[0])
    return video, served, f"{u:.1f},{v:.1f}"


WALL_MM = 700.0


def write_wall_video(folder, rig, frames: int = 6):
    """``frames`` frames (30/s, FFV1) of a grass-photo wall filling the view at 700 mm, the rig moving 0..-40 mm
    in depth over 3 positions, rendered through ``rig``: (path, true depth of every pixel per frame (mm))."""
    from psvs.io.video import write_video
    from psvs.live.simulated import SimulatedSequence, ping_pong_positions
    from psvs.simulate.builtin import photo_texture, regulated_light
    from psvs.simulate.scene import Scene
    scene = Scene((), regulated_light(WALL_MM), WALL_MM, photo_texture("grass", (1400.0, 1050.0)), "wall")
    positions = ping_pong_positions(frames, [0.0, 0.0, -40.0], 3)
    path = Path(folder) / "wall.avi"
    assert write_video(path, SimulatedSequence(scene, rig, positions, seed=5), fps=30.0) == frames
    return path, WALL_MM - positions[:, 2]


#: The hand-held card of the capture tests (psvs card-views' default card).
HAND_CARD = (4, 6, 14.0, 7.0)


@dataclasses.dataclass(frozen=True)
class HandVideo:
    """A simulated hand-held video (FFV1): its path, the frames' plan (kind and true poses, frame C), the
    target file, the rig it was rendered through."""

    path: Path
    plan: list
    target: Path
    rig: object


def write_hand_video(folder, rig_name: str = "misaligned", holds: int = 11, seed: int = 1, card=HAND_CARD,
                     frames: int | None = None, shared: bool = False, **hand) -> HandVideo:
    """A hand-held card (psvs.calibrate.handheld) through a shipped rig: ``holds`` poses, the first ``frames``
    frames of the path (all by default), written to FOLDER/hand.avi with FOLDER/target.toml. ``shared``: the
    video rendered once for the session's processes (tests/support/shared_files.py), FOLDER/hand.avi a link
    to it."""
    from psvs.calibrate.handheld import HandParams, hand_path, render_hand_video
    from psvs.io.video import write_video
    from psvs.simulate.textures import CircleGrid
    from psvs.targets.target_file import dumps_target
    from tests.support.shared_files import shared_file
    folder = Path(folder)
    rig, grid = load_rig(rig_name), CircleGrid(*card)
    plan = hand_path(rig, grid, holds, seed=seed, hand=HandParams(**hand))[:frames]
    (folder / "target.toml").write_text(dumps_target(grid))
    path = folder / "hand.avi"

    def render(to: Path):
        assert write_video(to, render_hand_video(rig, grid, plan, seed=seed), fps=30.0) == len(plan)

    if shared:
        key = "_".join(str(x) for x in (rig_name, holds, seed, card, frames, sorted(hand.items())))
        name = "hand-" + hashlib.sha256(key.encode()).hexdigest()[:16] + ".avi"
        path.symlink_to(shared_file(name, render))
    else:
        render(path)
    return HandVideo(path, plan, folder / "target.toml", rig)
