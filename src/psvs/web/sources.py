"""What ``psvs serve`` shows: a still complex image, a video file, a camera or a simulated scene.

A source gives the still image the page opens with and, except for a still image, a fresh frame iterator
for live mode with the source's nominal frame rate (the live loop plays files and simulations at that rate).
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from psvs.live.camera import Acquisition, CameraSpec
from psvs.live.simulated import SimulatedSequence, ping_pong_positions
from psvs.live.source import open_camera, open_video
from psvs.optics.rig import Rig
from psvs.simulate.render import render
from psvs.simulate.scene import Scene

#: A simulated scene's live sequence: the rig moves this far (mm) and back over this many distinct positions.
SIM_MOVE_MM = (0.0, 0.0, -150.0)
SIM_POSITIONS = 16


@dataclass(eq=False)
class Source:
    """kind: 'image', 'video', 'camera' or 'scene'; name: shown to the user; still: (H, W) uint8."""

    kind: str
    name: str
    still: np.ndarray
    fps: float = 0.0
    _open: object = field(default=None, repr=False)

    @property
    def live(self) -> bool:
        return self._open is not None

    def frames(self) -> Iterator[np.ndarray]:
        """A new iterator over the live frames (a file or a simulation loops; a camera runs until closed)."""
        if self._open is None:
            raise ValueError("a still image has no live frames: open a video in the Live or Capture step (or serve "
                             "a camera or a scene: psvs serve --camera, --scene)")
        return self._open()


def image_source(name: str, grey: np.ndarray) -> Source:
    """A still image (grey, (H, W)) served as a source of one frame, under ``name``."""
    return Source("image", name, grey)


def video_source(path: str) -> Source:
    """A video file, an image sequence or a folder of images, played in a loop. Read through once now: a file
    whose frame is damaged, or that ends before the frames its header declares, is refused here (DamagedVideo,
    naming it), not in the middle of a live run (trial 44: a truncated upload was taken, and live mode then
    failed on "DamagedVideo: /tmp/psvs-serve-video-...")."""
    with open_video(path) as v:
        first, fps = v.read(), v.fps
        for _ in v:
            pass
    if first is None:
        raise ValueError(f"no frame could be read from {path}")

    def frames():
        while True:
            n = 0
            with open_video(path) as v:
                for frame in v:
                    n += 1
                    yield frame
            if n == 0:
                return
    return Source("video", path, first, fps or 30.0, frames)


def camera_source(spec: CameraSpec, acquisition: Acquisition = Acquisition()) -> Source:
    """A camera (``--camera``: an OpenCV index or a machine-vision camera), opened and configured now to
    check it and take its first frame (one-line ValueError/OSError when it cannot), and again for each live
    run (a camera serves one program at a time: released between runs)."""
    def opened():
        source = open_camera(spec)
        try:
            source.open()
            source.configure(acquisition if spec.kind != "opencv" else Acquisition())
        except BaseException:
            source.close()
            raise
        return source

    with opened() as cam:
        first = cam.read()
    if first is None:
        raise OSError(f"camera {spec} gives no frames")

    def frames():
        with opened() as cam:
            yield from cam
    return Source("camera", f"camera {spec}", first, 0.0, frames)


def scene_source(name: str, scene: Scene, rig: Rig) -> Source:
    """The scene's complex image (2x2 supersampled); live: the rig moves along Z and back (rendered once per
    position, fresh noise every frame)."""
    still = render(scene, rig, seed=0).image
    period = 2 * (SIM_POSITIONS - 1)
    sim = SimulatedSequence(scene, rig, ping_pong_positions(period, SIM_MOVE_MM, SIM_POSITIONS), supersample=1)

    def frames():
        k = 0
        while True:
            yield sim.frame(k)
            k += 1
    return Source("scene", name, still, 30.0, frames)

