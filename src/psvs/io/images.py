"""Image and ground-truth files: 8-bit PNG and .npz, written atomically."""
from __future__ import annotations

import io
from pathlib import Path

import cv2
import numpy as np

from psvs._budget import check_memory
from psvs._quiet import c_stderr_captured, library_reason
from psvs._validate import check_grey
from psvs.imaging.grey import to_grey8
from psvs.io.atomic import write_atomic
from psvs.io.image_header import HeaderError, ImageHeader, read_header
from psvs.io.text import input_file


def write_png(path, image: np.ndarray) -> None:
    """Write an (H, W) uint8 image as an 8-bit grey PNG, atomically."""
    image = check_grey(image)
    ok, buf = cv2.imencode(".png", image)
    if not ok:
        raise OSError(f"could not encode PNG for {path}")
    write_atomic(path, buf.tobytes())


#: File suffixes of the images :func:`read_grey` reads (what :func:`psvs.io.image_header.read_header` knows: PNG,
#: JPEG, BMP, TIFF, PNM), for a command that takes every image of a folder.
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm", ".pnm")

#: Largest image :func:`read_grey` decodes, pixels (100 megapixels: 10000 x 10000 px, far above any sensor psvs
#: is used with), whatever the memory available.
MAX_IMAGE_PIXELS = 100_000_000


def read_grey(path, expect_size: tuple[int, int] | None = None) -> np.ndarray:
    """Read an image file as (H, W) uint8 grey; raise naming the file when it is missing or unreadable.

    The file is decoded by :func:`read_image`: refused from its header, before decoding, when its size
    differs from ``expect_size`` (W, H) px (e.g. the rig's sensor), exceeds :data:`MAX_IMAGE_PIXELS` or would
    not fit in the memory available.

    Colour images become grey by OpenCV's luma (0.299 R + 0.587 G + 0.114 B). A 16-bit image is scaled by
    its sensor's bit depth, found from its largest value (10, 12, 14 or 16 bits): a 12-bit camera's
    0..4095 becomes 0..255, not 0..15 (:func:`grey8_from_deep`)."""
    return grey8(read_image(path, expect_size), Path(path))


def read_image(path, expect_size: tuple[int, int] | None = None) -> np.ndarray:
    """An image file decoded as it is stored (``cv2.IMREAD_UNCHANGED``: (H, W) or (H, W, C), any depth).

    The size is read from the file's header first (:func:`psvs.io.image_header.read_header`: PNG, JPEG, BMP,
    TIFF, PNM) and the image refused before decoding when it differs from ``expect_size`` (W, H) px, exceeds
    :data:`MAX_IMAGE_PIXELS` or would not fit in the memory available: a small file claiming a huge image
    never reaches the decoder. What the decoder's libraries print (libpng's "libpng error: ...") is caught,
    never shown, and named in the one-line ValueError of a file that does not decode.
    FileNotFoundError("image not found: ...") when there is no such file."""
    path = input_file(path, "image")
    with path.open("rb") as f:
        try:
            header = read_header(f)
        except HeaderError as exc:
            raise ValueError(f"not a readable image: {path} ({exc})") from None
        _check_size(path, header, expect_size, path.stat().st_size)
        f.seek(0)
        data = np.frombuffer(f.read(), np.uint8)
    failure = None
    with c_stderr_captured() as said:
        try:
            img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
        except cv2.error as exc:
            img, failure = None, str(exc)
    if img is None:
        reason = library_reason([*said, *([failure] if failure else [])])
        raise ValueError(f"not a readable image: {path}" + (f" ({reason})" if reason else ""))
    if img.shape[:2] != (header.height, header.width):
        raise ValueError(f"not a readable image: {path} (its header says {header.width}x{header.height} px, "
                         f"it decodes to {img.shape[1]}x{img.shape[0]} px)")
    return img


def check_frame_size(image: np.ndarray, expect_size: tuple[int, int] | None, name) -> np.ndarray:
    """``image`` (H, W), already decoded (a video's frame), when it is ``expect_size`` (W, H) px or that is
    None; else the ValueError :func:`read_grey` gives a file of another size than the rig's camera."""
    h, w = image.shape[:2]
    if expect_size is not None and (w, h) != tuple(expect_size):
        ew, eh = expect_size
        raise ValueError(f"{name}: image is {w}x{h} px but the rig's camera is {ew}x{eh} px")
    return image


def _check_size(path: Path, header: ImageHeader, expect_size, file_bytes: int) -> None:
    """Refuse an image, from its header, whose size differs from ``expect_size`` (W, H) px, exceeds
    :data:`MAX_IMAGE_PIXELS` or whose decoding (the file, the decoded pixels and the grey copies made of them)
    would not fit in the memory available."""
    w, h = header.width, header.height
    if expect_size is not None and (w, h) != tuple(expect_size):
        ew, eh = expect_size
        raise ValueError(f"{path}: image is {w}x{h} px but the rig's camera is {ew}x{eh} px")
    if header.pixels > MAX_IMAGE_PIXELS:
        raise ValueError(f"{path}: image is {w}x{h} px ({header.pixels / 1e6:.0f} megapixels), more than the "
                         f"{MAX_IMAGE_PIXELS / 1e6:.0f} megapixels psvs reads")
    # decoded pixels, then the grey copy: a colour conversion (1 byte), or a 16-bit scaling in float64
    per_pixel = header.bytes_per_pixel + (24 if header.sample_bytes > 1 else 1)
    check_memory(file_bytes + header.pixels * per_pixel, f"image {path} ({w}x{h} px)")


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
    return grey8_from_bits(image, bits)


def grey8_from_bits(image: np.ndarray, bits: int) -> np.ndarray:
    """An (H, W) integer image of ``bits`` significant bits (a Mono10 or Mono12 camera's frame, known from its
    pixel format) as uint8: grey8 = round(value * 255 / (2**bits - 1)), the scaling :func:`grey8_from_deep`
    applies to a 16-bit file.

    >>> grey8_from_bits(np.array([[0, 2048, 4095]], np.uint16), 12).tolist()
    [[0, 128, 255]]
    """
    if bits == 8 and image.dtype == np.uint8:
        return image
    return to_grey8(image.astype(np.float64) * (255.0 / (2 ** bits - 1)))


def first_repeat(paths) -> tuple[int, int] | None:
    """The first (i, j), i < j, of ``paths`` whose files are one photograph: byte-identical (a copy under
    another name, SHA-256 of the bytes); missing files are skipped (their readers say so). None when every
    file is its own. A copy adds no view, yet a fit would weigh it as new evidence (calibration folders,
    hand-eye views)."""
    import hashlib
    first: dict[bytes, int] = {}
    for j, path in enumerate(paths):
        path = Path(path)
        if not path.is_file():
            continue
        digest = hashlib.sha256(path.read_bytes()).digest()
        if digest in first:
            return first[digest], j
        first[digest] = j
    return None


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
