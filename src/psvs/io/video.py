"""Lossless grey video files (FFV1 through OpenCV), written so that a file appears only when complete."""
from __future__ import annotations

import re
from pathlib import Path

import cv2

from psvs.io.text import input_file

VIDEO_SUFFIXES = (".avi", ".mkv")


def write_video(path, frames, fps: float = 30.0) -> int:
    """Write grey (H, W) uint8 frames to a lossless video (FFV1 in .avi or .mkv); returns the frame count.

    The file appears only when complete (written next to ``path``, then renamed)."""
    path = Path(path)
    if path.suffix.lower() not in VIDEO_SUFFIXES:
        raise ValueError(f"video {path} must end in .avi or .mkv (lossless FFV1)")
    if not path.parent.is_dir():
        raise FileNotFoundError(f"output folder does not exist: {path.parent}")
    tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")
    writer = None
    n = 0
    try:
        for frame in frames:
            if writer is None:
                h, w = frame.shape
                writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"FFV1"), fps, (w, h), isColor=False)
                if not writer.isOpened():
                    raise OSError(f"OpenCV cannot write FFV1 video: {path}")
            writer.write(frame)
            n += 1
        if writer is None:
            raise ValueError("no frames to write")
        writer.release()
        tmp.replace(path)
    finally:
        if writer is not None:
            writer.release()
        tmp.unlink(missing_ok=True)
    return n


#: What a decoder says of a frame it could not decode whole (FFmpeg's FFV1 "slice CRC mismatch", H.264's
#: "error while decoding MB" and "concealing N errors", libjpeg's "Corrupt JPEG data"): it then hands back the
#: last good frame or a mix of the two, not a new image.
DAMAGE = re.compile(r"crc|corrupt|conceal|error|invalid|damaged|missing|overread|truncat", re.IGNORECASE)


class DamagedVideo(ValueError):
    """A video file's frame that does not decode, or a file that ends before the frames its header declares:
    bad input, raised mid-stream (a live run stops there and keeps the frames before it)."""


def open_capture(path):
    """``cv2.VideoCapture`` of a video file decoding on one thread: a decoder's complaint about a frame then
    comes while that frame is read (with frame threads it comes with a neighbour's), so :func:`decoded`
    names the damaged frame (with frame threads the workers decode ahead, between reads, and a complaint can
    land outside any read). It costs 12-15 ms a 1440 x 1080 FFV1 frame (31-35 ms against 19-22 ms here)."""
    return cv2.VideoCapture(str(path), cv2.CAP_ANY, [cv2.CAP_PROP_N_THREADS, 1])


def decoded(cap, what: str, seek: int = 0):
    """``cap.read()`` (an open ``cv2.VideoCapture``) with the decoder's messages caught: (ok, image).
    :class:`DamagedVideo` naming ``what`` (e.g. "frame 3 of run.avi") when the decoder said the frame is damaged
    (:data:`DAMAGE`); its other messages are dropped. ``seek``: the frame index to go to first."""
    from psvs._quiet import c_stderr_captured, library_reason
    with c_stderr_captured() as said:
        if seek > 0 and not cap.set(cv2.CAP_PROP_POS_FRAMES, seek):     # seeking decodes: its words count
            raise ValueError(f"{what}: cannot seek to it")
        ok, image = cap.read()
    damage = [line for line in said if DAMAGE.search(line)]
    if damage:            # a seek decodes the frames before its target too: the complaint may be one of theirs
        which = f"{what}, or a frame before it that the seek decoded," if seek > 0 else what
        raise DamagedVideo(f"{which} is damaged: the decoder said \"{library_reason(damage)}\"")
    return ok, image


def open_video_file(path, what: str = "a video"):
    """The open ``cv2.VideoCapture`` of the video file ``path`` (:func:`open_capture`: one decoding thread).
    FileNotFoundError when there is no such file; ValueError naming it, with what the decoder said, when it
    cannot be opened ("not ``what`` OpenCV can decode")."""
    from psvs._quiet import c_stderr_captured, library_reason
    path = input_file(path, "video")
    with c_stderr_captured() as said:           # FFmpeg's complaints ("moov atom not found")
        cap = open_capture(path)
    if not cap.isOpened():
        reason = library_reason(said)
        raise ValueError(f"cannot open {path}: not {what} OpenCV can decode" + (f" ({reason})" if reason else ""))
    return cap


def video_frames(path) -> tuple[int, tuple[int, int]]:
    """(frame count, (W, H) px) of a video file, from its header; the frames counted by reading when the
    header does not say. ValueError when it does not open or holds no frame."""
    cap = open_video_file(path)
    try:
        n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
        size = (int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
        if n <= 0:
            from psvs._quiet import c_stderr_captured
            with c_stderr_captured():           # counted, not decoded: what the decoder says is for the reads
                while cap.grab():
                    n += 1
    finally:
        cap.release()
    if n <= 0:
        raise ValueError(f"{path}: the video holds no frame")
    return n, size


def read_video_frame(path, index: int):
    """Frame ``index`` (from 0) of a video file as grey (H, W) uint8 (OpenCV's luma of a colour frame, as
    ``psvs live`` reads it); the frame is sought, not read through (exact for FFV1, whose every frame is a
    key frame). ValueError when the video has no such frame."""
    from psvs.io.images import grey8
    cap = open_video_file(path)
    try:
        ok, frame = decoded(cap, f"frame {index} of {path}", seek=index)
    finally:
        cap.release()
    if not ok:
        raise ValueError(f"{path}: no frame {index}")
    return grey8(frame, f"{path} frame {index}")
