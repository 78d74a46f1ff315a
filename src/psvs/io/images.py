"""Image and ground-truth files: 8-bit PNG and .npz, written atomically."""
from __future__ import annotations

import io
from pathlib import Path

import cv2
import numpy as np

from psvs._validate import check_grey
from psvs.imaging.grey import to_grey8
from psvs.io.atomic import write_atomic


def write_png(path, image: np.ndarray) -> None:
    """Write an (H, W) uint8 image as an 8-bit grey PNG, atomically."""
    image = check_grey(image)
    ok, buf = cv2.imencode(".png", image)
    if not ok:
        raise OSError(f"could not encode PNG for {path}")
    write_atomic(path, buf.tobytes())


def read_grey(path) -> np.ndarray:
    """Read an image file as (H, W) uint8 grey; raise naming the file when it is missing or unreadable.

    Colour images become grey by OpenCV's luma (0.299 R + 0.587 G + 0.114 B). A 16-bit image is scaled by
    its sensor's bit depth, found from its largest value (10, 12, 14 or 16 bits): a 12-bit camera's
    0..4095 becomes 0..255, not 0..15 (:func:`grey8_from_deep`)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"image not found: {path}")
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ValueError(f"not a readable image: {path}")
    return grey8(img, path)


def grey8(img: np.ndarray, name) -> np.ndarray:
    """A decoded image (``cv2.IMREAD_UNCHANGED``: (H, W) or (H, W, C), uint8 or uint16) as (H, W) uint8 grey,
    as :func:`read_grey` describes; ``name`` (the file) is named in errors."""
    if img.ndim == 3:
        code = {1: None, 3: cv2.COLOR_BGR2GRAY, 4: cv2.COLOR_BGRA2GRAY}.get(img.shape[2], -1)
        if code == -1:
            raise ValueError(f"{name}: {img.shape[2]} channels; expected grey, colour (3) or colour+alpha (4)")
        img = img[:, :, 0] if code is None else cv2.cvtColor(img, code)
    if img.dtype == np.uint8:
        return img
    if img.dtype == np.uint16:
        return grey8_from_deep(img)
    raise ValueError(f"{name}: {img.dtype} pixels; expected 8- or 16-bit integers")


#: Sensor bit depths a 16-bit image file may hold.
DEEP_BITS = (10, 12, 14, 16)


def grey8_from_deep(image: np.ndarray) -> np.ndarray:
    """A 16-bit grey image (H, W) as uint8, scaled by the smallest bit depth in :data:`DEEP_BITS` that holds
    its largest value: grey8 = round(value * 255 / (2**bits - 1))."""
    top = int(image.max()) if image.size else 0
    bits = next(b for b in DEEP_BITS if top < 2 ** b)
    return to_grey8(image.astype(np.float64) * (255.0 / (2 ** bits - 1)))


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
