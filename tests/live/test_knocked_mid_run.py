"""A knock in the middle of a live run (trial 44): the mirrors moved after the first frame, the calibration not.
The first frame's rows test cannot see it, and `psvs live --seed` gave every later frame a depth 1.3-2.6 % off,
exit 0, even after its own rolling check had said the calibration drifted. Now each frame's pair is asked the
rows test (a pair that lines up rows off is an edge lost, not a depth), and while the rolling check says drifted
no frame is given a depth; the run says from which frame, and exits 1."""
import csv

import numpy as np
import pytest

from psvs.cli.main import main
from psvs.io.images import write_png
from psvs.io.params import load_rig
from psvs.simulate.builtin import builtin_scene, textured
from psvs.simulate.render import render
from psvs.simulate.sequence import render_sequence, straight_path


def _sequence(folder, images) -> str:
    folder.mkdir()
    for k, img in enumerate(images):
        write_png(folder / f"f_{k:03d}.png", img)
    return str(folder)


@pytest.mark.slow
def test_no_depth_while_the_rolling_check_says_drifted(tmp_path, capsys):
    """A still textured scene: 5 frames through the misaligned build, then 55 through it knocked (issue 43's
    knock), read with the build's calibration. The knocked frames' edge lines up with its twin (the rows test
    is not decisive on it), and reads 2.6 % near; the rolling check says drifted within the run, and from that
    frame on no depth is given (the log's depth empty, the line says why); exit 1, the last line naming the
    frame."""
    good = render(textured(), load_rig("misaligned"), supersample=1, seed=0).image
    bad = render(textured(), load_rig("misaligned_knocked"), supersample=1, seed=0).image
    video = _sequence(tmp_path / "seq", [good] * 5 + [bad] * 55)
    log = tmp_path / "live.csv"
    code = main(["live", "--video", video, "--rig", "misaligned", "--seed", "200,97", "-o", str(log),
                 "--check-share", "30"])
    out, err = capsys.readouterr()
    assert code == 1, (out, err)
    with log.open() as f:
        rows = list(csv.DictReader(f))
    drift = next(k for k, r in enumerate(rows) if r["health"] == "drifted")
    assert 5 < drift < 60
    assert err.strip().splitlines()[-1].startswith(f"psvs live: cannot measure from frame {drift} on: the "
                                                   "calibration has drifted (the twins stand off their rows")
    assert all(r["depth_mm"] == "" or not np.isfinite(float(r["depth_mm"])) for r in rows[drift:])
    assert f"frame {drift}: no depth: the calibration has drifted (psvs check, psvs refit)" in out
    z = [float(r["depth_mm"]) for r in rows[:5]]
    assert np.ptp(z) < 0.5 and all(np.isfinite(z))


def test_a_pair_off_the_rows_is_no_depth(tmp_path, capsys):
    """Fig. 5a moving away: 3 frames through the build, then 5 through it knocked. The knocked frames' pairs line
    up 2-3 rows off the rig's rows: each is an edge lost, said so, not a depth 1.3-1.6 % short (trial 44); the
    frames before are read within 0.5 % of the truth."""
    scene = builtin_scene("fig5a")
    poses = straight_path([0, 0, 0], [0, 0, -40], 8)
    frames = [r.image for r in render_sequence(scene, load_rig("misaligned"), poses[:3], supersample=1)]
    frames += [r.image for r in render_sequence(scene, load_rig("misaligned_knocked"), poses, supersample=1)][3:]
    video = _sequence(tmp_path / "seq", frames)
    log = tmp_path / "live.csv"
    code = main(["live", "--video", video, "--rig", "misaligned", "--seed", "548,330", "-o", str(log),
                 "--no-check"])
    out, err = capsys.readouterr()
    assert code == 0, err
    with log.open() as f:
        rows = list(csv.DictReader(f))
    truth = 650.0 + np.arange(8) * 40.0 / 7
    for k in range(3):
        assert float(rows[k]["depth_mm"]) == pytest.approx(truth[k], rel=0.005)
    lines = out.splitlines()
    for k in range(3, 8):
        assert rows[k]["depth_mm"] == "" or not np.isfinite(float(rows[k]["depth_mm"]))
        assert lines[k].startswith(f"frame {k}: edge lost (its twin lines up off the rig's rows: knocked?)"), lines[k]
