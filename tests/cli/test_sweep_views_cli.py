"""psvs sweep-views writes its images and sweep.csv as one batch (psvs.io.atomic.output_batch): a failure on the
last file leaves nothing of the new sweep (an adversarial trial found export-calibration's three files landing
one by one; the sweep's images then sweep.csv did the same)."""
import csv
import re

import numpy as np

from psvs.io.images import write_png
from tests.support.cli import run


def test_the_images_and_sweep_csv_land_together(tmp_path, capsys):
    folder = tmp_path / "sw"
    (folder / "sweep.csv").mkdir(parents=True)       # in the way of the last file
    args = ["sweep-views", str(folder), "--rig", "default", "--from-mm", "500", "--to-mm", "700", "--step-mm", "100"]
    code, _, err = run(capsys, *args)
    assert code == 2 and err.count("\n") == 1 and "sweep.csv: it is a folder" in err
    assert [p.name for p in folder.iterdir()] == ["sweep.csv"]
    (folder / "sweep.csv").rmdir()
    code, _, err = run(capsys, *args)
    assert code == 0, err
    with (folder / "sweep.csv").open() as f:      # the csv module: an independent reader
        rows = list(csv.reader(f))[1:]
    assert len(rows) == 3 and all((folder / r[0]).is_file() for r in rows)
    np.testing.assert_allclose(np.diff([float(r[1]) for r in rows]), 100.0)


def _rows(folder):
    with (folder / "sweep.csv").open() as f:      # the csv module: an independent reader
        return list(csv.reader(f))[1:]


def test_a_fine_step_names_every_position_and_a_new_sweep_replaces_the_old_images(tmp_path, capsys):
    """Trial 32: a step of 0.05 mm named its images with one decimal, so five positions went into three files,
    each overwritten by the last, and sweep.csv pointed readings at images of another depth (812.9000000000001
    among them); and a second sweep into the folder left the first one's images. Now every position has its
    own image, the readings are the depths less the robot's offset as typed, and only the new sweep's images
    remain."""
    folder = tmp_path / "sw"
    code, out, err = run(capsys, "sweep-views", str(folder), "--rig", "default", "--from-mm", "500", "--to-mm",
                         "500.2", "--step-mm", "0.05")
    assert code == 0, err
    rows = _rows(folder)
    names = [r[0] for r in rows]
    assert names == [f"sweep_0500_{k:02d}.png" for k in (0, 5, 10, 15, 20)]
    assert sorted(p.name for p in folder.glob("*.png")) == names
    readings = [float(r[1]) for r in rows]
    assert [r[1] for r in rows] == [repr(v) for v in readings] and max(len(r[1]) for r in rows) <= 6
    np.testing.assert_allclose(np.diff(readings), 0.05, atol=1e-9)
    code, out, err = run(capsys, "sweep-views", str(folder), "--rig", "default", "--from-mm", "700", "--to-mm",
                         "800", "--step-mm", "50")
    assert code == 0 and "removed 5 image(s) of an earlier sweep" in out, err
    assert sorted(p.name for p in folder.glob("*.png")) == sorted(r[0] for r in _rows(folder)) == [
        "sweep_0700_0.png", "sweep_0750_0.png", "sweep_0800_0.png"]


def test_calibrate_counts_every_image_it_skips(tmp_path, capsys):
    """Trial 32: a sweep of the misaligned build calibrated from the clear design read 2 of its 8 images and
    said "got 2 (skipped a; b; c)", three images unaccounted for. The refusal now counts the skipped of all
    and says how many it does not show. (That sweep itself now calibrates, every image used: the adjustment
    is made again from a plain least-squares fit before any image is dropped, psvs.calibrate.folder.) Six of
    its images replaced by noise, in which no pattern is found: refused, every skipped image counted."""
    folder = tmp_path / "swm"
    code, _, err = run(capsys, "sweep-views", str(folder), "--rig", "misaligned", "--step-mm", "100")
    assert code == 0, err
    images = sorted(folder.glob("sweep_*.png"))
    code, out, err = run(capsys, "calibrate", str(folder), "--rig", "clear", "-o", str(tmp_path / "c.toml"))
    assert code == 0 and out.startswith(f"used {len(images)} image(s)"), (code, err)
    rng = np.random.default_rng(0)
    for path in images[2:]:
        write_png(path, rng.integers(0, 256, (480, 640)).astype(np.uint8))
    code, _, err = run(capsys, "calibrate", str(folder), "--rig", "clear", "-o", str(tmp_path / "d.toml"))
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    got = int(re.search(r"usable images, got (\d+) ", err).group(1))
    skipped, total = (int(x) for x in re.search(r"\(skipped (\d+) of (\d+): ", err).groups())
    assert total == len(images) == got + skipped and got == 2
    more = re.search(r" and (\d+) more\)$", err.strip())
    assert err.count(".png: ") + (int(more.group(1)) if more else 0) == skipped
