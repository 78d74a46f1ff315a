"""Frame sources for live sensing that need no vendor SDK: OpenCV's VideoCapture (a video file or a camera
index) and image sequences (a printf pattern such as ``seq_%03d.png``, or a folder of images). Each is a
:class:`psvs.live.camera.FrameSource`; every frame is grey (H, W) uint8 (16-bit images scaled by their bit
depth, :func:`psvs.io.images.read_grey`)."""
from __future__ import annotations

import contextlib
import re
import time
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

import cv2
import numpy as np

from psvs._quiet import c_stderr_captured, python_stderr_aside
from psvs.io import DamagedVideo, decoded, open_video_file
from psvs.io.images import IMAGE_SUFFIXES
from psvs.live.camera import (
    VENDORS,
    Acquisition,
    CameraLost,
    CameraSpec,
    Frame,
    FrameSource,
    parse_camera,
    vendor_module,
)

#: Image files a folder given as a sequence may hold (read in name order): every format psvs reads.
SEQUENCE_SUFFIXES = IMAGE_SUFFIXES


class _Source:
    """What the sources here share: frames counted, iteration over images, ``with``, no settings."""

    name: str = ""
    fps: float = 0.0
    frame_count: int = 0
    _index: int = 0
    _t0: float | None = None

    def configure(self, acquisition: Acquisition) -> None:
        if acquisition.asks_anything():
            raise ValueError(f"{self.name} takes no acquisition settings (exposure, gain, frame rate, pixel "
                             "format, trigger, features): those are for a machine-vision camera "
                             "(--camera basler:SERIAL)")

    def settings(self) -> dict:
        return {"source": self.name}

    def feature_file(self) -> str | None:
        return None

    def _frame(self, image: np.ndarray, file_clock: bool) -> Frame:
        """The next Frame: on the file's clock (k / fps) when it has a rate, else the host's at arrival."""
        k = self._index
        self._index += 1
        now = time.monotonic()
        if self._t0 is None:
            self._t0 = now
        if file_clock and self.fps > 0:
            return Frame(image, k, k, k / self.fps, "file")
        return Frame(image, k, k, now - self._t0, "host")

    def read(self) -> np.ndarray | None:
        """The next frame's image (H, W) uint8, or None at the end of the stream."""
        frame = self.grab()
        return None if frame is None else frame.image

    def __iter__(self) -> Iterator[np.ndarray]:
        while (frame := self.read()) is not None:
            yield frame

    def __enter__(self):
        self.open()
        return self

    def __exit__(self, *exc):
        self.close()


class VideoSource(_Source):
    """Frames from ``cv2.VideoCapture``: a file path or a camera index (a printf pattern or a folder is an
    :class:`ImageSequence`: use :func:`open_video`).

    Colour frames are converted to grey. ``fps`` is the source's nominal rate (0 when unknown). Opened at
    construction unless ``defer`` (then by :meth:`open` or ``with``); iterate for images or :meth:`grab`
    for :class:`~psvs.live.camera.Frame`s, and close it (or use ``with``).

    A file's next frame is decoded on a thread while the caller works on this one, from the second frame
    read on (as a camera's driver fills its next buffer): a live run's frame time is then its own work, not
    the decoder's too (FFV1 at 1440 x 1080: about 25 ms a frame on one core). A damaged frame is still
    raised by the :meth:`grab` that reaches it, and the frames come in the file's order.
    """

    def __init__(self, video: str | None = None, camera: int | None = None, defer: bool = False):
        if (video is None) == (camera is None):
            raise ValueError("give exactly one of video (a file) or camera (an index)")
        if camera is not None and (not isinstance(camera, int) or camera < 0):
            raise ValueError(f"camera must be an index >= 0, got {camera!r}")
        self._video, self._camera, self._cap, self._last = video, camera, None, None
        self._decoder: ThreadPoolExecutor | None = None     # a file's read-ahead (one thread), from frame 1
        self._ahead: Future | None = None                   # ... and the frame it decodes
        self._held = contextlib.ExitStack()                 # ... and python_stderr_aside while it runs
        self.name = str(video) if video is not None else f"camera {camera}"
        if video is not None and "%" not in str(video) and not Path(video).is_file():
            raise FileNotFoundError(f"video not found: {video}")
        if not defer:
            self.open()

    def open(self) -> None:
        """Open the video file or camera (ValueError naming it, with what the decoder said, when it cannot be
        opened); opening an open source does nothing."""
        if self._cap is not None:
            return
        if self._video is not None:
            cap = open_video_file(self._video, "a video or image sequence")
        else:
            with c_stderr_captured():               # OpenCV's and V4L2's log of each backend it tried
                cap = cv2.VideoCapture(self._camera)
            if not cap.isOpened():
                raise OSError(f"cannot open camera {self._camera}: no such camera, or another program is using it")
        self._cap = cap
        self.fps = float(cap.get(cv2.CAP_PROP_FPS) or 0.0)
        self.frame_count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)

    def grab(self) -> Frame | None:
        """The next frame, or None at the end of a file; CameraLost when a camera stops delivering;
        :class:`~psvs.io.video.DamagedVideo` on a damaged frame or when a file ends before the frame count its
        header declares (a truncated file: its last frames are
        lost, and a run over it must not pass for a run over the whole video)."""
        if self._cap is None:
            raise ValueError(f"{self.name} is not open")
        ok, image = self._read()
        if ok and self._video is not None and self._index >= 1:       # the next one decodes meanwhile
            if self._decoder is None:       # Python's prints kept off the decoder's caught descriptor meanwhile
                self._held.enter_context(python_stderr_aside())
                self._decoder = ThreadPoolExecutor(1, thread_name_prefix="psvs-decode")
            self._ahead = self._decoder.submit(self._decode, self._index + 1)
        if not ok:
            if self._video is None:             # a camera has no end: it stopped delivering
                raise CameraLost(f"{self.name} gives no more frames", self._last)
            if 0 < self._index < self.frame_count:
                raise DamagedVideo(f"{self.name} ends after {self._index} of the {self.frame_count} frames its header "
                                 "declares: the file is truncated or damaged")
            return None
        self._last = self._frame(image, self._video is not None)
        return self._last

    def _read(self):
        """The next (ok, image grey): a file's damaged frame (:func:`psvs.io.video.decoded`) is a ValueError naming
        it. A camera's frames are read as they come: many MJPEG webcams' decoder says "Corrupt JPEG data" of
        every frame while delivering whole images, so its words do not tell a damaged frame there."""
        if self._video is None:
            ok, image = self._cap.read()
            return ok, (as_grey(image) if ok else image)
        if self._ahead is not None:
            ahead, self._ahead = self._ahead, None
            return ahead.result()
        return self._decode(self._index)

    def _decode(self, index: int):
        """(ok, the frame grey) of a file's next frame, whose index is ``index`` (:func:`psvs.io.video.decoded`)."""
        ok, image = decoded(self._cap, f"frame {index} of {self.name}")
        return ok, (as_grey(image) if ok else image)

    def close(self) -> None:
        """Release the file or camera (after the frame being read ahead, if any); closing a closed source does
        nothing."""
        if self._decoder is not None:
            self._decoder.shutdown(wait=True)
            self._decoder, self._ahead = None, None
            self._held.close()
        if self._cap is not None:
            self._cap.release()
            self._cap = None


class ImageSequence(_Source):
    """Frames from image files: a printf pattern (``seq_%03d.png``: from the first index 0..999 that exists to
    the first missing one) or a folder (its images in name order). Each is read with
    :func:`psvs.io.images.read_grey`: colour becomes grey, a 16-bit image is scaled by its bit depth."""

    def __init__(self, pattern: str, fps: float = 0.0):
        self.name, self.fps = str(pattern), float(fps)
        self._files = sequence_files(str(pattern))
        if not self._files:
            raise FileNotFoundError(f"no image of the sequence {pattern} found")
        self.frame_count = len(self._files)
        self._open = False

    def open(self) -> None:
        """Start reading the sequence from its first file."""
        self._open = True

    def grab(self) -> Frame | None:
        """The next file's frame, or None after the last."""
        from psvs.io.images import read_grey
        if not self._open:
            raise ValueError(f"{self.name} is not open")
        if self._index >= len(self._files):
            return None
        try:
            image = read_grey(self._files[self._index])
        except (OSError, ValueError) as exc:        # a frame the sequence names but no image: the run stops there
            raise DamagedVideo(str(exc)) from None
        return self._frame(image, True)

    def close(self) -> None:
        """Stop reading the sequence."""
        self._open = False


#: The widest frame number a sequence pattern may ask for (``%012d``: a trillion frames).
MAX_INDEX_DIGITS = 12


def check_pattern(pattern: str) -> bool:
    """Whether ``pattern`` is a printf sequence pattern: exactly one frame number ``%d`` / ``%0Nd`` (N at most
    :data:`MAX_INDEX_DIGITS`; ``%%`` is a literal %). ValueError, in one short line, for a pattern with
    another field, two numbers, or a wider number (``%999999999d`` would make gigabyte names)."""
    fields = re.findall(r"%(%|[^%]*?[a-zA-Z])", pattern)
    numbers = [f for f in fields if f != "%"]
    if not numbers:
        return False
    shown = pattern if len(pattern) <= 80 else pattern[:77] + "..."
    width = re.fullmatch(r"0?(\d*)d", numbers[0])
    if len(numbers) > 1 or width is None:
        raise ValueError(f"image sequence pattern {shown!r}: give one frame number, %d or %0Nd (e.g. seq_%03d.png)")
    if width[1] and int(width[1]) > MAX_INDEX_DIGITS:
        raise ValueError(f"image sequence pattern {shown!r}: a frame number of {width[1]} digits; at most "
                         f"{MAX_INDEX_DIGITS}")
    return True


def sequence_files(pattern: str) -> list[Path]:
    """The image files of a sequence: a folder's entries named as images (:data:`SEQUENCE_SUFFIXES`; a folder or a
    dangling link so named too, for its reader to refuse) in name order, or a printf
    pattern's files (:func:`check_pattern`) from the first index 0..999 that exists to the first missing
    one, ValueError when frames of the pattern follow that gap (an adversarial trial: q_005..007 and q_010,
    q_011 gave a batch of 3 frames, "3 ok", the rest never read); [] when none."""
    path = Path(pattern)
    if path.is_dir():
        # every entry named as a frame, readable or not: a dangling link or a folder named x.png is a frame the
        # reader then refuses by name, not one left out without a word
        return sorted(p for p in path.iterdir() if p.suffix.lower() in SEQUENCE_SUFFIXES)
    if not check_pattern(pattern):
        return []
    start = next((k for k in range(1000) if Path(pattern % k).is_file()), None)
    files, k = [], start
    while k is not None and Path(pattern % k).is_file():
        files.append(Path(pattern % k))
        k += 1
    after = sorted(i for i in _numbered(pattern) if k is not None and i > k)
    if after:
        raise ValueError(f"image sequence {pattern}: {Path(pattern % k).name} is missing, yet {len(after)} "
                         f"frame(s) of the pattern follow it (from {Path(pattern % after[0]).name}): fill the gap, "
                         f"or give the frames' folder")
    return files


def _numbered(pattern: str) -> list[int]:
    """The frame numbers of the files in ``pattern``'s folder that its name matches (a checked pattern)."""
    folder, name = Path(pattern).parent, Path(pattern).name
    parts = re.split(r"(%%|%0?\d*d)", name)
    regex = re.compile("".join("%" if part == "%%" else r"( *\d+)" if part.startswith("%") else re.escape(part)
                               for part in parts))
    try:
        names = {p.name for p in folder.iterdir()} if folder.is_dir() else set()
    except OSError:
        return []
    found = (int(m[1]) for m in map(regex.fullmatch, names) if m is not None)
    return [i for i in found if Path(pattern % i).name in names]      # as the pattern writes it (q_5 not q_005)


def open_video(video: str, fps: float = 0.0) -> _Source:
    """The source of a ``--video``: an image sequence for a printf pattern or a folder, else a video file
    (opened now; FileNotFoundError or a one-line ValueError when it is not one)."""
    if "%" in str(video) or Path(video).is_dir():
        source = ImageSequence(video, fps)
        source.open()
        return source
    return VideoSource(video=video)


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


def open_camera(spec) -> FrameSource:
    """The source a ``--camera`` spec names (not yet opened: use ``with`` or :meth:`FrameSource.open`)."""
    spec = spec if isinstance(spec, CameraSpec) else parse_camera(spec)
    if spec.kind == "opencv":
        return VideoSource(camera=int(spec.device), defer=True)
    return getattr(vendor_module(spec.kind), VENDORS[spec.kind][1])(spec.device)
