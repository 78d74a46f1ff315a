"""`psvs live` on a simulated video through the machine-vision rigs (1440 x 1080 px, twice the paper
camera's pixels per degree: the tracker's search and jump limits scale with the camera, psvs.optics.scale)."""
import csv

import numpy as np
import pytest

from psvs.cli.main import main
from psvs.io.params import load_rig
from psvs.io.video import write_video
from psvs.live.simulated import SimulatedSequence, disc_scene, ping_pong_positions
from psvs.live.tracker import TrackerParams
from psvs.optics.scale import pixel_scale
from tests.support.scenes import rim_seed


def test_the_tracker_scales_its_pixel_limits_with_the_camera():
    """Its px limits are the paper camera's: 8 mm on 3.45 um pixels sees 8 / 0.00345 / 1130 = 2.052 times
    as many px per degree, so a 30 mm step in depth at 700 mm (12 px of disparity on mv1440, 6 on the
    paper's camera) stays within the jump limit."""
    from psvs.live.tracker import EdgeTracker
    rig = load_rig("mv1440")
    assert pixel_scale(rig.camera) == pytest.approx(8 / 0.00345 / 1130, rel=1e-12)
    tr = EdgeTracker(rig, (700.0, 500.0))
    p = TrackerParams()
    assert tr.params.max_jump_px == pytest.approx(p.max_jump_px * 2.0520713, rel=1e-6)
    assert tr.params.search_px == pytest.approx(p.search_px * 2.0520713, rel=1e-6)
    assert EdgeTracker(load_rig("default"), (300.0, 200.0)).params.max_jump_px == pytest.approx(p.max_jump_px)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["mv1440", "mv1440_misaligned"])
def test_live_cli_on_a_simulated_video(name, tmp_path, capsys):
    """A 1 s video at 30 frames/s of a disc moving 30 mm in depth (and sideways) between six positions:
    every frame tracked, each depth within 0.5 % of the truth."""
    rig = load_rig(name)
    scene = disc_scene(z_mm=700.0, radius_mm=30.0, x_mm=15.0, y_mm=-20.0)
    positions = ping_pong_positions(30, [-20.0, 12.0, -150.0], 6)
    path = tmp_path / "disc.avi"
    assert write_video(path, SimulatedSequence(scene, rig, positions, seed=11), fps=30.0) == 30
    truth = 700.0 - positions[:, 2]
    u, v = rim_seed(rig, scene, positions[0])
    log = tmp_path / "log.csv"
    assert main(["live", "--video", str(path), "--rig", name, "--seed", f"{u:.1f},{v:.1f}", "-o", str(log)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[-1].startswith("30 frames, 30 tracked, "), out[-1]
    rows = list(csv.DictReader(log.open()))
    depth = np.array([float(r["depth_mm"]) for r in rows])
    assert np.abs(depth / truth - 1).max() <= 0.005
