"""A calibration folder's images are every file psvs reads (README: PNG, JPEG, BMP, TIFF or PNM, grey or
colour), not its PNGs only: a camera that saves JPEG views had them silently ignored ('needs at least 3
usable images, got 0' with nothing skipped)."""
import cv2
import numpy as np
import pytest

from psvs.calibrate.folder import calibrate_folder
from psvs.io.images import IMAGE_SUFFIXES, read_grey
from psvs.io.params import load_rig
from psvs.simulate.textures import CircleGrid
from psvs.targets.target_file import dumps_target


def test_every_image_format_of_a_folder_is_read(tmp_path):
    """Blank frames (each its own grey) in each format psvs reads, a colour JPEG among them: each is read and
    skipped for what it shows (no disc; the message names the first three), none ignored; a text file is not an
    image."""
    names = []
    for k, suffix in enumerate(IMAGE_SUFFIXES):
        blank = np.full((480, 640), 30 + 5 * k, np.uint8)
        frame = cv2.cvtColor(blank, cv2.COLOR_GRAY2BGR) if suffix in (".jpg", ".ppm") else blank
        ok, buf = cv2.imencode(".pgm" if suffix == ".pnm" else suffix, frame)
        assert ok, suffix
        names.append(f"view_{k}{suffix}")
        (tmp_path / names[-1]).write_bytes(buf.tobytes())
        assert read_grey(tmp_path / names[-1]).shape == (480, 640)
    (tmp_path / "notes.txt").write_text("not an image")
    (tmp_path / "target.toml").write_text(dumps_target(CircleGrid(4, 6, 14.0, 7.0)))
    with pytest.raises(ValueError, match="needs at least 3 usable images, got 0") as err:
        calibrate_folder(tmp_path, load_rig("clear"))
    for name in sorted(names)[:3]:     # view_0.png, view_1.jpg (colour), view_2.jpeg
        assert f"{name}: found 0 disc(s)" in str(err.value), name
    assert "notes.txt" not in str(err.value)
