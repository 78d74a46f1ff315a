"""Bad (and good) input files for the corpus, made without psvs's own writers where the file is the point:
rig files edited as text from the shipped default, images encoded by OpenCV or written byte by byte."""
from __future__ import annotations

import struct
import zlib
from pathlib import Path

import cv2
import numpy as np

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
DEFAULT_RIG = (EXAMPLES / "rigs" / "default.toml").read_text(encoding="utf-8")
MISALIGNED_RIG = (EXAMPLES / "rigs" / "misaligned.toml").read_text(encoding="utf-8")


def rig_text(old: str = "", new: str = "", extra: str = "", base: str = DEFAULT_RIG) -> str:
    """The default rig file with ``old`` replaced by ``new`` (which must be there) and ``extra`` appended."""
    if old:
        assert old in base, old
        base = base.replace(old, new, 1)
    return base + extra


def nested(depth: int = 5000) -> str:
    """A TOML file whose one value is an array nested ``depth`` deep."""
    return "[camera]\nfocal_length_mm = " + "[" * depth + "1" + "]" * depth + "\n"


def png(image: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", image)
    assert ok
    return buf.tobytes()


def noise_png(w: int = 640, h: int = 480, seed: int = 0) -> bytes:
    """Independent random grey levels: no structure, no echo."""
    return png(np.random.default_rng(seed).integers(0, 256, (h, w), dtype=np.uint8))


def flat_png(w: int = 640, h: int = 480, level: int = 128) -> bytes:
    return png(np.full((h, w), level, np.uint8))


def texture_png(w: int = 640, h: int = 480, seed: int = 1) -> bytes:
    """Smooth random texture (blurred noise): edges everywhere, a plausible image of the right size."""
    img = np.random.default_rng(seed).random((h, w))
    img = cv2.GaussianBlur(img, (0, 0), 3.0)
    img = (img - img.min()) / (img.max() - img.min())
    return png(np.rint(img * 255).astype(np.uint8))


def repeating_png(period: int = 40, w: int = 640, h: int = 480, seed: int = 5) -> bytes:
    """A random texture tiled every ``period`` px along the rows with dark joints (bricks), one view: no twin,
    and it matches itself at every multiple of its period."""
    rng = np.random.default_rng(seed)
    tile = rng.random((h, period)) * 80 + 60
    tile[:, :3] = 30
    img = np.tile(tile, (1, w // period + 1))[:, :w] + rng.normal(0, 2, (h, w))
    return png(np.clip(img, 0, 255).astype(np.uint8))


def npy(array) -> bytes:
    """``array`` as the bytes of a .npy file (NumPy's own format)."""
    import io
    buf = io.BytesIO()
    np.save(buf, np.asarray(array))
    return buf.getvalue()


def truncated_png() -> bytes:
    return texture_png()[:2000]


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def png_claiming(w: int, h: int) -> bytes:
    """A small PNG whose header (IHDR, valid CRC) claims w x h px: an image bomb for a decoder that trusts it."""
    ihdr = struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0)
    idat = zlib.compress(b"\x00" * 64)
    return b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr) + _chunk(b"IDAT", idat) + _chunk(b"IEND", b"")


BOM = "\ufeff"
