"""Image files as psvs reads them: 8-bit grey as is, colour by luma, 16-bit by the sensor's bit depth."""
import cv2
import numpy as np
import pytest

from psvs.io.images import grey8_from_deep, read_grey, write_png


@pytest.fixture
def ramp():
    rng = np.random.default_rng(5)
    return rng.integers(0, 256, (30, 40)).astype(np.uint8)


def test_8bit_grey_png_round_trips_by_value(tmp_path, ramp):
    write_png(tmp_path / "g.png", ramp)
    assert np.array_equal(cv2.imread(str(tmp_path / "g.png"), cv2.IMREAD_UNCHANGED), ramp)  # independent reader
    assert np.array_equal(read_grey(tmp_path / "g.png"), ramp)


@pytest.mark.parametrize("bits", [10, 12, 14, 16])
def test_deep_png_is_scaled_by_its_bit_depth(tmp_path, bits):
    """A full-scale ramp of a `bits`-bit sensor in a 16-bit PNG comes back as 0..255 (within rounding)."""
    top = 2 ** bits - 1
    deep = np.linspace(0, top, 40 * 30).reshape(30, 40).astype(np.uint16)
    cv2.imwrite(str(tmp_path / "d.png"), deep)
    got = read_grey(tmp_path / "d.png")
    assert got.dtype == np.uint8 and got.max() == 255 and got.min() == 0
    assert np.abs(got - deep / top * 255.0).max() <= 0.5 + 1e-9


def test_dark_12bit_image_keeps_its_brightness():
    """Largest value 3000 needs 12 bits: 3000 -> 3000/4095*255 = 186.8 -> 187 (not stretched to 255)."""
    img = np.array([[0, 1000, 3000]], np.uint16)
    assert grey8_from_deep(img).tolist() == [[0, 62, 187]]


def test_colour_png_becomes_luma(tmp_path, ramp):
    bgr = np.dstack([ramp, np.roll(ramp, 1, 0), np.roll(ramp, 2, 1)])
    cv2.imwrite(str(tmp_path / "c.png"), bgr)
    expected = np.rint(0.114 * bgr[..., 0] + 0.587 * bgr[..., 1] + 0.299 * bgr[..., 2])
    assert np.abs(read_grey(tmp_path / "c.png").astype(float) - expected).max() <= 1
    bgra = np.dstack([bgr, np.full_like(ramp, 255)])
    cv2.imwrite(str(tmp_path / "a.png"), bgra)
    assert np.array_equal(read_grey(tmp_path / "a.png"), read_grey(tmp_path / "c.png"))


def test_float_tiff_is_refused_by_name(tmp_path):
    cv2.imwrite(str(tmp_path / "f.tiff"), np.ones((8, 8), np.float32))
    with pytest.raises(ValueError, match=r"f\.tiff: float32 pixels; expected 8- or 16-bit integers"):
        read_grey(tmp_path / "f.tiff")


def test_first_repeat_finds_the_first_copy_as_filecmp_does(tmp_path):
    """psvs.io.images.first_repeat against the standard library's byte comparison over random folders."""
    import filecmp

    from psvs.io.images import first_repeat
    rng = np.random.default_rng(3)
    for trial in range(20):
        folder = tmp_path / str(trial)
        folder.mkdir()
        contents = [rng.integers(0, 256, 64, dtype=np.uint8).tobytes() for _ in range(4)]
        paths = []
        for k in range(6):
            p = folder / f"{k}.png"
            p.write_bytes(contents[int(rng.integers(0, 4))] if rng.random() < 0.5 else rng.bytes(64))
            paths.append(p)
        paths.append(folder / "missing.png")              # skipped: its reader says it is missing
        expected = next(((i, j) for j in range(6) for i in range(j)
                         if filecmp.cmp(paths[i], paths[j], shallow=False)), None)
        assert first_repeat(paths) == expected
