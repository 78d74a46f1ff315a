"""End to end on the machine-vision rig: a simulated hand-held video of a card through the misaligned build
(mv1440_misaligned, 1440x1080), the capture assistant on it through the nominal design (mv1440), and psvs
calibrate on the folder it saved: true correspondences over 400-1200 mm triangulate within 0.1 mm mean after
the rigid motion no card view can fix (docs/calibration.md, "What images cannot see")."""
import re

import numpy as np
import pytest

from psvs.io.params import load_rig
from tests.support.cli import run
from tests.support.geometry import reconstruction_errors
from tests.support.video import write_hand_video

pytestmark = pytest.mark.slow


def test_capture_then_calibrate_mv1440(capsys, tmp_path):
    """25 poses held 3 frames each (2 partly out of the image), one motion-blurred frame between them, of
    the issue's 5 x 7 card (16 mm, discs 7 mm: 96 mm wide, wider than its disparity at every depth held, so
    its two views interleave and a disc of each may be lost where their columns meet). The assistant saves
    20 views covering every bin; calibration from the nominal design reprojects within 0.06 px and
    reconstructs within 0.1 mm (rigid motion taken out) over 400-1200 mm, the nominal design 143 mm."""
    video = write_hand_video(tmp_path, "mv1440_misaligned", holds=25, seed=7, card=(5, 7, 16.0, 7.0),
                             hold_frames=3, move_frames=1, blur_samples=2, out_every=12, apart=False, shared=True)
    views = tmp_path / "views"
    code, text, err = run(capsys, "capture", "--video", str(video.path), "--target", str(video.target),
                          "--rig", "mv1440", "-o", str(views))
    assert code == 0, err
    saved = re.findall(r"^frame (\d+): saved (view_\d\d\.png)", text, re.M)
    assert len(saved) == 20 and all(video.plan[int(k)].kind == "still" for k, _ in saved)
    code, text, err = run(capsys, "calibrate", str(views), "--rig", "mv1440", "-o", str(tmp_path / "rig.toml"))
    assert code == 0 and "skipped" not in err, err
    assert "used 20 image(s) (20 grid)" in text
    rms = float(re.search(r"reprojection RMS ([0-9.]+) px", text)[1])
    assert rms <= 0.06
    raw, aligned, pts = reconstruction_errors(load_rig(tmp_path / "rig.toml"), video.rig)
    assert pts[:, 2].min() == 400.0 and pts[:, 2].max() == 1200.0 and len(pts) > 300
    print(f"3-D error over 400-1200 mm after the rigid motion: mean {aligned.mean():.3f} mm, max {aligned.max():.3f} "
          f"mm; in frame C {raw.mean():.2f} mm; RMS {rms:.4f} px")
    # Issue 27 asks 0.1 mm: measured 0.065 mm (2026-11-25; seed 3: 0.072 mm). A small 4 x 6 card of 6 mm
    # discs held apart gave 0.09-0.12 mm (24 points a view): the card set that, not the assistant.
    assert np.mean(aligned) <= 0.1
    _, nominal, _ = reconstruction_errors(load_rig("mv1440"), video.rig)
    assert np.mean(nominal) > 10.0                 # the build is far from its design: calibration did this
