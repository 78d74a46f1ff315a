"""psvs sweep-views writes its images and sweep.csv as one batch (psvs.io.atomic.output_batch): a failure on the
last file leaves nothing of the new sweep (an adversarial trial found export-calibration's three files landing
one by one; the sweep's images then sweep.csv did the same)."""
import csv

import numpy as np

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
