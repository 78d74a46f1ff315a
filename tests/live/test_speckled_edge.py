"""An object whose grey crosses the pipeline's threshold turns its area to speckle: the tracker refuses that
frame's edge as the sensor's noise (as ``match`` refuses the frame), on a later frame and as a first frame,
instead of a depth from pairs of speckle (an adversarial trial: 743.7 mm for 740 on 640 pairs, exit 0)."""
import numpy as np
import pytest

from psvs.cli.main import main
from psvs.io.params import load_rig
from psvs.live.source import VideoSource
from psvs.live.tracker import EdgeTracker

#: The trial's scene: a bright disc before a dark backdrop, moving away 150 mm over 6 frames; under the
#: simulator's light its grey falls through the paper's threshold (92) at frame 3 (740 mm).
SCENE = """name = "disc"
[backdrop]
z_mm = 1400
albedo = 0.15
[[objects]]
name = "disc"
type = "disc"
radius_mm = 35
position_mm = [20, 10, 650]
albedo = 0.85
"""
SEED = (378, 256)


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("speckle")
    (tmp / "disc.toml").write_text(SCENE)
    video, truth = tmp / "dd.avi", tmp / "dd.npz"
    assert main(["simulate", str(tmp / "disc.toml"), "--rig", "default", "--frames", "6", "--move-mm", "20,0,-150",
                 "-o", str(video), "--truth", str(truth)]) == 0
    with VideoSource(video=str(video)) as src:
        out = [src.read() for _ in range(6)]
    return out, [650.0, 680.0, 710.0, 740.0, 770.0, 800.0]


def test_the_speckled_frame_is_lost_not_measured(frames):
    images, truth = frames
    tracker = EdgeTracker(load_rig("default"), SEED)
    steps = [tracker.step(f) for f in images]
    assert [s.ok for s in steps[:3]] == [True, True, True]
    for s, z in zip(steps[:3], truth[:3], strict=True):
        assert s.depth_mm == pytest.approx(z, rel=0.001)
    assert not steps[3].ok and np.isnan(steps[3].depth_mm)
    assert "sensor's noise" in steps[3].message, steps[3].message
    for s, z in zip(steps, truth, strict=True):       # whatever is answered is right
        assert not s.ok or abs(s.depth_mm / z - 1) <= 0.002, (s.frame, s.depth_mm, z)


def test_the_speckled_frame_as_a_first_frame_is_refused_for_that(frames):
    images, _ = frames
    step = EdgeTracker(load_rig("default"), SEED).step(images[3])
    assert not step.ok and np.isnan(step.depth_mm)
    assert step.message.startswith("the seed's edge is not the scene's: the pipeline's edges are mostly the sensor's "
                                   "noise"), step.message
