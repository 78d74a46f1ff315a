"""Image and ground-truth files: 8-bit PNG and .npz, written atomically."""
from __future__ import annotations

import io
from pathlib import Path

import cv2
import numpy as np

from psvs.io.atomic import write_atomic


def write_png(path, image: np.ndarray) -> None:
    """Write an (H, W) uint8 image as an 8-bit grey PNG, atomically."""
    if image.dtype != np.uint8 or image.ndim != 2:
        raise ValueError(f"image must be (H, W) uint8, got {image.shape} {image.dtype}")
    ok, buf = cv2.imencode(".png", image)
    if not ok:
        raise OSError(f"could not encode PNG for {path}")
    write_atomic(path, buf.tobytes())


def to_grey8(image) -> np.ndarray:
    """Grey levels (any real dtype, any shape) rounded and clipped to 0..255, uint8."""
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def read_grey(path) -> np.ndarray:
    """Read an image file as (H, W) uint8 grey; raise naming the file when it is missing or unreadable."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"image not found: {path}")
    img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise ValueError(f"not a readable image: {path}")
    return img


def write_npy(path, array: np.ndarray) -> None:
    """Write one array as a NumPy .npy file, atomically."""
    buf = io.BytesIO()
    np.save(buf, array)
    write_atomic(path, buf.getvalue())


def write_npz(path, **arrays) -> None:
    """Write arrays to a compressed .npz, atomically."""
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    write_atomic(path, buf.getvalue())
