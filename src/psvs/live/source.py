"""Frame sources for live sensing: OpenCV VideoCapture (a video file, an image sequence such as
``seq_%03d.png``, or a camera index) and in-memory frames. Every source yields grey (H, W) uint8 frames."""
from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from psvs.io.cstderr import c_stderr_captured, library_reason


class VideoSource:
    """Frames from ``cv2.VideoCapture``: a file path (or printf-style image sequence) or a camera index.

    Colour frames are converted to grey. ``fps`` is the source's nominal rate (0 when unknown).
    Use as an iterator (frames until the end of the stream) and close it (or use ``with``).
    """

    def __init__(self, video: str | None = None, camera: int | None = None):
        if (video is None) == (camera is None):
            raise ValueError("give exactly one of video (a file) or camera (an index)")
        if video is not None:
            video = str(video)
            if "%" not in video and not Path(video).is_file():
                raise FileNotFoundError(f"video not found: {video}")
            self.name = video
            with c_stderr_captured() as said:       # FFmpeg's complaints ("moov atom not found")
                self._cap = cv2.VideoCapture(video)
            if not self._cap.isOpened():
                reason = library_reason(said)
                raise ValueError(f"cannot open {video}: not a video or image sequence OpenCV can decode"
                                 + (f" ({reason})" if reason else ""))
        else:
            if not isinstance(camera, int) or camera < 0:
                raise ValueError(f"camera must be an index >= 0, got {camera!r}")
            self.name = f"camera {camera}"
            with c_stderr_captured():               # OpenCV's and V4L2's log of each backend it tried
                self._cap = cv2.VideoCapture(camera)
            if not self._cap.isOpened():
                raise OSError(f"cannot open camera {camera}: no such camera, or another program is using it")
        self.fps = float(self._cap.get(cv2.CAP_PROP_FPS) or 0.0)
        self.frame_count = int(self._cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)

    def read(self) -> np.ndarray | None:
        """The next frame (H, W) uint8, or None at the end of the stream."""
        ok, frame = self._cap.read()
        if not ok:
            return None
        return as_grey(frame)

    def __iter__(self) -> Iterator[np.ndarray]:
        while (frame := self.read()) is not None:
            yield frame

    def close(self) -> None:
        self._cap.release()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def as_grey(frame: np.ndarray) -> np.ndarray:
    """A decoded frame (H, W), (H, W, 3) BGR or (H, W, 4) BGRA as grey (H, W) uint8."""
    if frame.dtype != np.uint8:
        raise ValueError(f"frames must be 8-bit, got {frame.dtype}")
    if frame.ndim == 2:
        return frame
    if frame.ndim == 3 and frame.shape[2] == 3:
        return cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    if frame.ndim == 3 and frame.shape[2] == 4:
        return cv2.cvtColor(frame, cv2.COLOR_BGRA2GRAY)
    raise ValueError(f"frames must be (H, W) grey or (H, W, 3) colour, got shape {frame.shape}")
