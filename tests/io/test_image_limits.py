"""Image files psvs refuses, from their headers before decoding or from the decoder's failure, in one line
naming the file -- and never with what the C decoders print on stderr."""
import os
import struct
import zlib

import cv2
import numpy as np
import pytest

from psvs._quiet import c_stderr_captured, library_reason
from psvs.io import images
from psvs.io.image_header import HeaderError, read_header
from psvs.io.images import MAX_IMAGE_PIXELS, read_grey, read_image, write_png


@pytest.fixture(scope="module")
def noise():
    """A 480 x 640 image of noise: its PNG does not compress, so half the file is half the image."""
    return np.random.default_rng(7).integers(0, 256, (480, 640)).astype(np.uint8)


def colour(grey):
    return np.dstack([grey, np.roll(grey, 3, 0), np.roll(grey, 5, 1)])


KINDS = {"g8.png": lambda g: g, "g16.png": lambda g: g.astype(np.uint16) * 250, "c8.png": colour,
         "ca.png": lambda g: np.dstack([colour(g), g]), "g.jpg": lambda g: g, "c.jpg": colour, "g.bmp": lambda g: g,
         "c.bmp": colour, "g8.tif": lambda g: g, "g16.tif": lambda g: g.astype(np.uint16) * 250,
         "c16.tif": lambda g: colour(g).astype(np.uint16) * 250, "f.tiff": lambda g: g.astype(np.float32),
         "g.pgm": lambda g: g, "g16.pgm": lambda g: g.astype(np.uint16) * 250, "c.ppm": colour,
         "g.pam": lambda g: g, "g.pfm": lambda g: g.astype(np.float32)}


@pytest.mark.parametrize("name", KINDS)
def test_the_header_gives_the_size_that_decodes(tmp_path, noise, name):
    """Written by OpenCV, read back by the header alone: the size, channels and sample bytes of the decode."""
    img = KINDS[name](noise[:31, :47])
    path = tmp_path / name
    assert cv2.imwrite(str(path), img)
    decoded = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    with path.open("rb") as f:
        h = read_header(f)
    assert (h.height, h.width) == decoded.shape[:2] == (31, 47)
    assert h.sample_bytes == decoded.dtype.itemsize
    channels = decoded.shape[2] if decoded.ndim == 3 else 1
    # a BMP's header gives its bits per pixel, not whether its palette is grey: 3 channels, an upper bound
    assert h.channels == channels if h.format != "BMP" else h.channels >= channels


def test_the_jpeg_frame_header_is_found_after_large_segments(tmp_path, noise):
    ok, buf = cv2.imencode(".jpg", colour(noise))
    data = buf.tobytes()
    app1 = b"\xff\xe1" + struct.pack(">H", 60000) + b"\x00" * 59998       # two big Exif-like segments
    path = tmp_path / "exif.jpg"
    path.write_bytes(data[:2] + app1 + app1 + data[2:])
    with path.open("rb") as f:
        h = read_header(f)
    assert (h.format, h.width, h.height, h.channels) == ("JPEG", 640, 480, 3)
    assert read_grey(path).shape == (480, 640)


def test_a_bigtiff_header(tmp_path):
    entries = [(256, 4, 1, 640), (257, 3, 1, 480), (258, 3, 1, 16)]
    data = b"II+\x00" + struct.pack("<HHQ", 8, 0, 16) + struct.pack("<Q", len(entries))
    data += b"".join(struct.pack("<HHQQ", *e) for e in entries)
    path = tmp_path / "big.tif"
    path.write_bytes(data)
    with path.open("rb") as f:
        h = read_header(f)
    assert (h.format, h.width, h.height, h.channels, h.sample_bytes) == ("TIFF", 640, 480, 1, 2)


def png_claiming(data: bytes, width: int, height: int) -> bytes:
    """A PNG's bytes with its IHDR's size replaced (and the chunk's CRC made valid again)."""
    b = bytearray(data)
    b[16:24] = struct.pack(">II", width, height)
    b[29:33] = struct.pack(">I", zlib.crc32(bytes(b[12:29])))
    return bytes(b)


@pytest.fixture
def no_decode(monkeypatch):
    """Fail a test that reaches the decoder."""
    def refuse(*args):
        raise AssertionError("the image was decoded")
    monkeypatch.setattr(images.cv2, "imdecode", refuse)


def test_an_image_bomb_is_refused_from_its_header(tmp_path, noise, no_decode):
    good = tmp_path / "good.png"
    write_png(good, noise)
    bomb = tmp_path / "bomb.png"
    bomb.write_bytes(png_claiming(good.read_bytes(), 100000, 100000))
    assert zlib.crc32(bomb.read_bytes()[12:29]) == struct.unpack(">I", bomb.read_bytes()[29:33])[0]
    with pytest.raises(ValueError) as info:
        read_grey(bomb)
    assert str(info.value) == (f"{bomb}: image is 100000x100000 px (10000 megapixels), more than the "
                               f"{MAX_IMAGE_PIXELS // 1_000_000} megapixels psvs reads")
    with pytest.raises(ValueError, match=rf"^{bomb}: image is 100000x100000 px but the rig's camera is 640x480 px$"):
        read_grey(bomb, expect_size=(640, 480))


def test_an_image_of_another_size_than_expected_is_refused_before_decoding(tmp_path, noise, no_decode):
    path = tmp_path / "small.png"
    write_png(path, noise[:240, :320])
    with pytest.raises(ValueError, match=rf"^{path}: image is 320x240 px but the rig's camera is 640x480 px$"):
        read_grey(path, expect_size=(640, 480))


def test_an_image_beyond_the_memory_available_is_refused_before_decoding(tmp_path, noise, no_decode, monkeypatch):
    import psvs._budget
    path = tmp_path / "n.png"
    write_png(path, noise)
    monkeypatch.setattr(psvs._budget, "available_bytes", lambda: 100_000)
    with pytest.raises(ValueError, match=rf"^image {path} \(640x480 px\) needs about .* of memory, more than the"):
        read_grey(path)


def test_the_expected_size_is_met(tmp_path, noise):
    path = tmp_path / "n.png"
    write_png(path, noise)
    assert np.array_equal(read_grey(path, expect_size=(640, 480)), noise)


def test_a_truncated_png_is_one_line_and_libpng_says_nothing(tmp_path, noise, capfd):
    path = tmp_path / "cut.png"
    write_png(tmp_path / "n.png", noise)
    data = (tmp_path / "n.png").read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(ValueError) as info:
        read_grey(path)
    msg = str(info.value)
    assert msg.startswith(f"not a readable image: {path} (libpng error: ") and "\n" not in msg, msg
    out, err = capfd.readouterr()
    assert err == "" and out == ""


@pytest.mark.parametrize("name, content, reason", [
    ("text.png", b"not a PNG at all\n", "not a PNG, JPEG, BMP, TIFF or PNM"),
    ("empty.png", b"", r"the file is empty \(0 bytes\)"),
    ("head.png", b"\x89PNG\r\n\x1a\n\x00\x00", "the file is cut short inside its header"),
    ("zero.png", None, "claims a size of 0x480 px"),
    ("riff.webp", b"RIFF\x00\x00\x00\x00WEBPVP8 ", "not a PNG, JPEG, BMP, TIFF or PNM"),
])
def test_files_that_are_not_images(tmp_path, noise, name, content, reason, no_decode):
    path = tmp_path / name
    if content is None:
        write_png(tmp_path / "n.png", noise)
        content = png_claiming((tmp_path / "n.png").read_bytes(), 0, 480)
    path.write_bytes(content)
    with pytest.raises(ValueError, match=rf"^not a readable image: {path} \(.*{reason}"):
        read_grey(path)


@pytest.mark.parametrize("name", ["n.jpg", "n.bmp"])
def test_truncated_jpeg_and_bmp(tmp_path, noise, name, capfd):
    assert cv2.imwrite(str(tmp_path / name), colour(noise))
    data = (tmp_path / name).read_bytes()
    path = tmp_path / f"cut_{name}"
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(ValueError, match=rf"^not a readable image: {path}"):
        read_grey(path)
    assert capfd.readouterr().err == ""


def test_a_16bit_png_and_a_colour_jpeg_read_as_grey(tmp_path, noise):
    deep = noise.astype(np.uint16) * 16            # a 12-bit sensor's values
    cv2.imwrite(str(tmp_path / "d.png"), deep)
    assert np.abs(read_grey(tmp_path / "d.png").astype(int) - noise).max() <= 1
    bgr = colour(noise)
    cv2.imwrite(str(tmp_path / "c.jpg"), bgr, [cv2.IMWRITE_JPEG_QUALITY, 100])
    luma = 0.114 * bgr[..., 0] + 0.587 * bgr[..., 1] + 0.299 * bgr[..., 2]
    got = read_grey(tmp_path / "c.jpg")
    assert got.shape == (480, 640) and np.abs(got - luma).mean() < 8    # JPEG's loss on noise
    assert read_image(tmp_path / "c.jpg").shape == (480, 640, 3)


def test_a_header_error_is_a_value_error():
    assert issubclass(HeaderError, ValueError)


def test_c_stderr_is_caught_and_restored(capfd):
    with c_stderr_captured() as said:
        os.write(2, b"libpng error: Read Error\n\n  second line \n")
    os.write(2, b"after\n")
    assert said == ["libpng error: Read Error", "second line"]
    assert capfd.readouterr().err == "after\n"
    with c_stderr_captured() as outer:           # nested: each restores what it found
        with c_stderr_captured() as inner:
            os.write(2, b"inner\n")
        os.write(2, b"outer\n")
    assert (inner, outer) == (["inner"], ["outer"])
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize("lines, reason", [
    (["[ERROR:0@0.100] global loadsave.cpp:1409 imdecode_ imdecode_(''): can't read data: OpenCV(4.14.0) "
      "/io/opencv/modules/imgcodecs/src/bitstrm.cpp:59: error: (-2:Unspecified error) Unexpected end of input "
      "stream in function 'readBlock'"], "Unexpected end of input stream"),
    (["OpenCV(4.14.0) color.hpp:92: error: (-15:Bad number of channels) in function 'cv::CvtHelper'\n> more"],
     "Bad number of channels"),
    (["[mov,mp4,m4a,3gp,3g2,mj2 @ 0x55fe1076ba00] moov atom not found"], "moov atom not found"),
    (["", "libpng error: Read Error"], "libpng error: Read Error"),
    ([], ""),
])
def test_library_reason(lines, reason):
    assert library_reason(lines) == reason
