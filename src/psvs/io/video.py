"""Lossless grey video files (FFV1 through OpenCV), written so that a file appears only when complete."""
from __future__ import annotations

from pathlib import Path

import cv2

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
