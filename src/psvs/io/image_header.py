"""An image file's size read from its header bytes, before anything is decoded.

A small file can claim a huge image (a PNG of a few hundred bytes whose IHDR says 100000 x 100000 px): the
decoder would then raise deep inside OpenCV or allocate gigabytes. :func:`read_header` reads the width, the
height and the decoded bytes per pixel from the header of the formats psvs reads -- PNG (IHDR), JPEG (the
SOF marker), BMP, TIFF (the first IFD, classic and BigTIFF) and the Netpbm family (PBM, PGM, PPM, PAM, PFM)
-- so the caller can refuse an image before decoding it. The format is found from the file's first bytes,
not its name.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import BinaryIO

#: The formats :func:`read_header` knows, as named in errors.
FORMATS = "PNG, JPEG, BMP, TIFF or PNM (PBM, PGM, PPM, PAM, PFM)"

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
# JPEG start-of-frame markers (every SOFn but DHT 0xC4, JPG 0xC8 and DAC 0xCC), which carry the size
_JPEG_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}
# JPEG markers without a length: TEM, RST0-7, SOI
_JPEG_BARE = {0x01, 0xD8, *range(0xD0, 0xD8)}
#: Most JPEG segments walked before the frame header (an APP segment is at most 64 KiB).
JPEG_MAX_SEGMENTS = 1000
#: Most TIFF directory entries read (a real first IFD has a few dozen).
TIFF_MAX_ENTRIES = 4096


class HeaderError(ValueError):
    """The header is not one of :data:`FORMATS`, or is cut short or inconsistent."""


@dataclass(frozen=True)
class ImageHeader:
    """What a header says: the format, the size (px), the channels OpenCV decodes and the bytes of each
    channel's sample (1 for 8-bit, 2 for 16-bit, 4 for 32-bit float)."""

    format: str
    width: int
    height: int
    channels: int
    sample_bytes: int

    @property
    def pixels(self) -> int:
        return self.width * self.height

    @property
    def bytes_per_pixel(self) -> int:
        return self.channels * self.sample_bytes


def read_header(f: BinaryIO) -> ImageHeader:
    """The header of the image file open in ``f`` (binary, seekable; read from its start); HeaderError when
    it is none of :data:`FORMATS` or is cut short, or claims a zero size."""
    f.seek(0)
    head = f.read(16)
    if not head:                            # (a trial's frame written as 0 bytes was "not a PNG, JPEG ... file")
        raise HeaderError("the file is empty (0 bytes)")
    if head.startswith(PNG_SIGNATURE):
        h = _png(f)
    elif head.startswith(b"\xff\xd8"):
        h = _jpeg(f)
    elif head.startswith(b"BM"):
        h = _bmp(f)
    elif head[:4] in (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+"):
        h = _tiff(f, head)
    elif len(head) >= 2 and head[0:1] == b"P" and head[1:2] in b"1234567fF":
        h = _netpbm(f)
    else:
        raise HeaderError(f"not a {FORMATS} file")
    if h.width <= 0 or h.height <= 0:
        raise HeaderError(f"its {h.format} header claims a size of {h.width}x{h.height} px")
    return h


def _read_at(f: BinaryIO, offset: int, n: int) -> bytes:
    f.seek(offset)
    data = f.read(n)
    if len(data) != n:
        raise HeaderError("the file is cut short inside its header")
    return data


def _png(f: BinaryIO) -> ImageHeader:
    chunk = _read_at(f, 8, 8 + 13)
    if chunk[4:8] != b"IHDR":
        raise HeaderError("PNG without an IHDR chunk first")
    width, height, depth, colour = struct.unpack(">IIBB", chunk[8:18])
    # colour types: 0 grey, 2 RGB, 3 palette (decoded as BGR), 4 grey + alpha and 6 RGBA (decoded as BGRA)
    channels = {0: 1, 2: 3, 3: 3, 4: 4, 6: 4}.get(colour)
    if channels is None:
        raise HeaderError(f"PNG colour type {colour} is not one of 0, 2, 3, 4, 6")
    return ImageHeader("PNG", width, height, channels, 2 if depth == 16 else 1)


def _jpeg(f: BinaryIO) -> ImageHeader:
    pos = 2
    for _ in range(JPEG_MAX_SEGMENTS):
        if _read_at(f, pos, 1) != b"\xff":
            raise HeaderError("JPEG segment without a marker")
        marker = _read_at(f, pos + 1, 1)[0]
        if marker == 0xFF:              # a fill byte before the marker
            pos += 1
            continue
        if marker in _JPEG_BARE:
            pos += 2
            continue
        if marker in (0xD9, 0xDA):      # end of image, or the scan, before any frame header
            raise HeaderError("JPEG without a frame header (SOF) before its data")
        length = struct.unpack(">H", _read_at(f, pos + 2, 2))[0]
        if marker in _JPEG_SOF:
            precision, height, width, components = struct.unpack(">BHHB", _read_at(f, pos + 4, 6))
            return ImageHeader("JPEG", width, height, max(components, 1), 2 if precision > 8 else 1)
        if length < 2:
            raise HeaderError("JPEG segment of a length below 2")
        pos += 2 + length
    raise HeaderError(f"JPEG without a frame header (SOF) in its first {JPEG_MAX_SEGMENTS} segments")


def _bmp(f: BinaryIO) -> ImageHeader:
    info = _read_at(f, 14, 4)
    (size,) = struct.unpack("<I", info)
    if size == 12:                      # OS/2 BITMAPCOREHEADER: 16-bit size
        width, height, _, bits = struct.unpack("<HHHH", _read_at(f, 18, 8))
    else:
        width, height, _, bits = struct.unpack("<iiHH", _read_at(f, 18, 12))
    return ImageHeader("BMP", width, abs(height), 4 if bits == 32 else 3, 1)   # negative height: top-down rows


def _tiff(f: BinaryIO, head: bytes) -> ImageHeader:
    end = "<" if head[:2] == b"II" else ">"
    big = head[2:4] in (b"+\x00", b"\x00+")
    if big:
        offset = struct.unpack(end + "Q", _read_at(f, 8, 8))[0]
        count = struct.unpack(end + "Q", _read_at(f, offset, 8))[0]
        entry_size, first = 20, offset + 8
    else:
        offset = struct.unpack(end + "I", _read_at(f, 4, 4))[0]
        count = struct.unpack(end + "H", _read_at(f, offset, 2))[0]
        entry_size, first = 12, offset + 2
    if count > TIFF_MAX_ENTRIES:
        raise HeaderError(f"TIFF directory of {count} entries (more than {TIFF_MAX_ENTRIES})")
    tags = {}
    for k in range(count):
        entry = _read_at(f, first + k * entry_size, entry_size)
        tag, kind = struct.unpack(end + "HH", entry[:4])
        if tag in (256, 257, 258, 277):     # width, length (height), bits per sample, samples per pixel
            tags[tag] = _tiff_first_value(f, end, big, kind, entry)
    if 256 not in tags or 257 not in tags:
        raise HeaderError("TIFF whose first directory has no ImageWidth or ImageLength")
    bits, samples = tags.get(258, 1), tags.get(277, 1)
    return ImageHeader("TIFF", tags[256], tags[257], max(samples, 1), max((bits + 7) // 8, 1))


def _tiff_first_value(f: BinaryIO, end: str, big: bool, kind: int, entry: bytes) -> int:
    """The first value of a TIFF directory entry of integers (SHORT, LONG or LONG8): held in the entry when
    every value fits there, else at the offset the entry holds."""
    fmt, size = {3: ("H", 2), 4: ("I", 4), 16: ("Q", 8)}.get(kind, (None, 0))
    if fmt is None:
        raise HeaderError(f"TIFF size field of type {kind} (expected SHORT, LONG or LONG8)")
    count = struct.unpack(end + ("Q" if big else "I"), entry[4:12] if big else entry[4:8])[0]
    field = entry[12:20] if big else entry[8:12]
    if count * size <= len(field):
        return struct.unpack(end + fmt, field[:size])[0]
    offset = struct.unpack(end + ("Q" if big else "I"), field)[0]
    return struct.unpack(end + fmt, _read_at(f, offset, size))[0]


def _netpbm(f: BinaryIO) -> ImageHeader:
    f.seek(0)
    text = f.read(4096).decode("latin-1")
    kind = text[1]
    if kind == "7":
        return _pam(text)
    words = []
    for line in text[2:].splitlines():
        words += line.split("#", 1)[0].split()
        if len(words) >= 3:
            break
    need = 2 if kind in "14" else 3
    try:
        values = [int(w) if k < 2 else float(w) for k, w in enumerate(words[:need])]
    except ValueError:
        raise HeaderError(f"P{kind} header with a size that is not a number: {' '.join(words[:need])}") from None
    if len(values) < need:
        raise HeaderError(f"P{kind} header cut short")
    width, height = values[0], values[1]
    if kind in "fF":                    # PFM: 32-bit floats, grey (Pf) or colour (PF)
        return ImageHeader("PFM", width, height, 1 if kind == "f" else 3, 4)
    return ImageHeader("PNM", width, height, 3 if kind in "36" else 1, 2 if need == 3 and values[2] > 255 else 1)


def _pam(text: str) -> ImageHeader:
    fields = {}
    for line in text.splitlines()[1:]:
        words = line.split("#", 1)[0].split()
        if words and words[0] == "ENDHDR":
            break
        if len(words) >= 2:
            fields[words[0]] = words[1]
    try:
        width, height = int(fields["WIDTH"]), int(fields["HEIGHT"])
        depth, top = int(fields.get("DEPTH", 1)), int(fields.get("MAXVAL", 255))
    except (KeyError, ValueError):
        raise HeaderError("PAM header without a WIDTH and HEIGHT") from None
    return ImageHeader("PAM", width, height, max(depth, 1), 2 if top > 255 else 1)
