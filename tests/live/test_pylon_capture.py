"""`psvs capture --camera basler:0` end to end on pylon's emulator serving a simulated hand-held card sequence
through the 1440x1080 machine-vision build (the same sequence as tests/calibrate/test_capture_e2e.py's video,
as PNG frames): the set it saves calibrates to what `psvs capture --video` gives on that video."""
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import cv2
import numpy as np
import pytest

from psvs.io.params import load_rig
from tests.support.cli import run
from tests.support.geometry import reconstruction_errors
from tests.support.video import write_hand_video

pytestmark = pytest.mark.slow
ROOT = Path(__file__).resolve().parents[2]


def test_capture_from_the_emulated_camera_calibrates(capsys, tmp_path):
    """25 poses held 3 frames each, served by the emulated camera (software trigger, the camera's region of
    interest set to 1440x1080): the assistant saves 20 views of still cards and stops; the folder holds the
    camera's settings (camera.toml, camera.pfs) beside the views; calibration from the nominal design
    reprojects within 0.06 px and reconstructs within issue 27's 0.1 mm over 400-1200 mm (rigid motion taken
    out), the figures of the video path (the issue's 5x7 card, its two views interleaving)."""
    video = write_hand_video(tmp_path, "mv1440_misaligned", holds=25, seed=7, card=(5, 7, 16.0, 7.0),
                             hold_frames=3, move_frames=1, blur_samples=2, out_every=12, apart=False, shared=True)
    frames = tmp_path / "frames"
    frames.mkdir()
    cap = cv2.VideoCapture(str(video.path))
    k = 0
    while True:
        ok, img = cap.read()
        if not ok:
            break
        cv2.imwrite(str(frames / f"f{k:05d}.png"), cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img)
        k += 1
    cap.release()
    assert k == len(video.plan)
    views = tmp_path / "views"
    env = dict(os.environ, PYLON_CAMEMU="1", PYTHONPATH=str(ROOT / "src"))
    proc = subprocess.run([sys.executable, "-m", "psvs", "capture", "--camera", "basler:0", "--trigger", "software",
                           "--camera-set", "Width=1440", "--camera-set", "Height=1080",
                           "--camera-set", "TestImageSelector=Off", "--camera-set", "ImageFileMode=On",
                           "--camera-set", f"ImageFilename={frames}", "--target", str(video.target),
                           "--rig", "mv1440", "-o", str(views)], capture_output=True, text=True, timeout=1800, env=env)
    assert proc.returncode == 0, proc.stderr
    saved = re.findall(r"^frame (\d+): saved (view_\d\d\.png)", proc.stdout, re.M)
    assert len(saved) == 20 and all(video.plan[int(k)].kind == "still" for k, _ in saved)
    assert {"camera.toml", "camera.pfs", "target.toml"} <= {p.name for p in views.iterdir()}
    recorded = tomllib.loads((views / "camera.toml").read_text())          # an independent reader
    assert recorded["camera"]["acquisition"]["pixel_format"] == "Mono8"
    code, text, err = run(capsys, "calibrate", str(views), "--rig", "mv1440", "-o", str(tmp_path / "rig.toml"))
    assert code == 0 and "skipped" not in err, err
    rms = float(re.search(r"reprojection RMS ([0-9.]+) px", text)[1])
    raw, aligned, pts = reconstruction_errors(load_rig(tmp_path / "rig.toml"), video.rig)
    print(f"camera path: 3-D error over 400-1200 mm after the rigid motion: mean {aligned.mean():.3f} mm, "
          f"max {aligned.max():.3f} mm; RMS {rms:.4f} px")
    assert rms <= 0.06 and np.mean(aligned) <= 0.1
