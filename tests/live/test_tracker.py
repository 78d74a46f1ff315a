"""Live tracking on a simulated video: every frame's depth against the disc's planted depth."""
import csv

import numpy as np
import pytest

from psvs.cli.main import main
from psvs.io.video import write_video
from psvs.live.simulated import ping_pong_positions
from psvs.live.source import VideoSource, as_grey
from psvs.live.tracker import EdgeTracker, TrackerParams, nearest_edge_pixels
from tests.support.geometry import EXAMPLES
from tests.support.scenes import rim_seed

RIG_FILE = str(EXAMPLES / "rigs" / "default.toml")


def test_live_cli_depth_every_frame(disc_video, tmp_path, capsys):
    """`psvs live` on a 3 s video: every frame tracked, depth within 0.5 % of the truth."""
    path, truth, rig, scene, positions = disc_video
    u, v = rim_seed(rig, scene, positions[0])
    log = tmp_path / "log.csv"
    assert main(["live", "--video", str(path), "--rig", RIG_FILE, "--seed", f"{u:.1f},{v:.1f}",
                 "-o", str(log)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("frame 0: Z ") and out[-1].startswith("90 frames, 90 tracked, ")
    rows = list(csv.DictReader(log.open()))
    assert [int(r["frame"]) for r in rows] == list(range(90))
    depth = np.array([float(r["depth_mm"]) for r in rows])
    assert all(r["tracked"] == "1" for r in rows)
    err = np.abs(depth / truth - 1)
    assert err.max() <= 0.005, (err.max(), int(err.argmax()))
    assert err.mean() <= 0.002


def test_tracker_loses_and_finds_the_edge_again(disc_video):
    path, truth, rig, scene, positions = disc_video
    with VideoSource(video=str(path)) as src:
        frames = [src.read() for _ in range(3)]
    blank = np.full_like(frames[0], 20)
    tr = EdgeTracker(rig, rim_seed(rig, scene, positions[0]))
    steps = [tr.step(f) for f in (frames[0], frames[1], blank, frames[2])]
    assert [s.ok for s in steps] == [True, True, False, True]
    assert steps[2].message == "edge lost" and np.isnan(steps[2].depth_mm) and steps[2].seed_px is None
    assert steps[3].depth_mm == pytest.approx(truth[2], rel=0.005)
    assert [s.frame for s in steps] == [0, 1, 2, 3]


def test_tracker_reports_a_seed_far_from_any_edge(disc_video):
    path, _, rig, _, _ = disc_video
    with VideoSource(video=str(path)) as src:
        frame = src.read()
    step = EdgeTracker(rig, (20, 20)).step(frame)
    assert not step.ok and step.message == "no edge pixel near the seed"


def test_tracker_bad_input(rig):
    with pytest.raises(ValueError, match=r"seed \(700, 10\) is outside the 640x480 image"):
        EdgeTracker(rig, (700, 10))
    with pytest.raises(ValueError, match="seed must be two numbers"):
        EdgeTracker(rig, ("a", 1))
    with pytest.raises(ValueError, match="search_px must be > 0 px"):
        EdgeTracker(rig, (10, 10), params=TrackerParams(search_px=0))
    tr = EdgeTracker(rig, (10, 10))
    with pytest.raises(ValueError, match="frame is 320x240 px but the rig's camera is 640x480 px"):
        tr.step(np.zeros((240, 320), np.uint8))
    with pytest.raises(ValueError, match="frame must be a grey"):
        tr.step(np.zeros((480, 640), np.float64))


def test_nearest_edge_pixels():
    edges = np.zeros((50, 60), bool)
    edges[10, 20] = edges[12, 25] = edges[40, 5] = True
    np.testing.assert_array_equal(nearest_edge_pixels(edges, (21, 11), 10, k=3), [[20, 10], [25, 12]])
    assert nearest_edge_pixels(edges, (50, 40), 3).shape == (0, 2)
    assert nearest_edge_pixels(edges, (-100, -100), 3).shape == (0, 2)


def test_ping_pong_positions():
    p = ping_pong_positions(7, [0, 0, -30], 4)
    np.testing.assert_allclose(p[:, 2], [0, -10, -20, -30, -20, -10, 0])
    with pytest.raises(ValueError, match="distinct must be >= 2"):
        ping_pong_positions(5, [0, 0, 1], 1)


def test_video_source_and_writer_errors(tmp_path):
    with pytest.raises(ValueError, match="give exactly one of video"):
        VideoSource()
    with pytest.raises(FileNotFoundError, match="video not found"):
        VideoSource(video=str(tmp_path / "nope.avi"))
    with pytest.raises(ValueError, match="must end in .avi or .mkv"):
        write_video(tmp_path / "x.mp4", [np.zeros((4, 4), np.uint8)])
    with pytest.raises(ValueError, match="frames must be"):
        as_grey(np.zeros((4, 4, 2), np.uint8))
    # a lossless round trip
    frames = [np.random.default_rng(k).integers(0, 256, (48, 64), dtype=np.uint8) for k in range(3)]
    write_video(tmp_path / "r.avi", frames, fps=25)
    with VideoSource(video=str(tmp_path / "r.avi")) as src:
        assert src.fps == 25 and all(np.array_equal(a, b) for a, b in zip(src, frames, strict=True))


@pytest.mark.parametrize("args, message", [
    (["--video", "missing.avi", "--seed", "1,2"], "video not found: missing.avi"),
    (["--video", "x.avi", "--seed", "1"], "--seed must be 'u,v'"),
    (["--video", "x.avi", "--seed", "1,2", "-o", "log.txt"], "must end in .csv"),
    (["--video", "x.avi", "--seed", "1,2", "--max-frames", "0"], "--max-frames must be >= 1"),
])
def test_live_cli_errors(args, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["live", "--rig", RIG_FILE, *args]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_live_cli_image_sequence_and_max_frames(disc_video, tmp_path, capsys):
    """An image sequence (printf pattern) is a video too; --max-frames stops early; --quiet prints the summary."""
    import cv2
    path, truth, rig, scene, positions = disc_video
    with VideoSource(video=str(path)) as src:
        for k in range(4):
            cv2.imwrite(str(tmp_path / f"seq_{k:03d}.png"), src.read())
    u, v = rim_seed(rig, scene, positions[0])
    assert main(["live", "--video", str(tmp_path / "seq_%03d.png"), "--rig", RIG_FILE, "--seed", f"{u},{v}",
                 "--max-frames", "3", "--quiet", "--no-check"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 1 and out[0].startswith("3 frames, 3 tracked, ")
    # a seed far from any edge: nothing tracked, exit status 1 and the reason
    assert main(["live", "--video", str(tmp_path / "seq_%03d.png"), "--rig", RIG_FILE, "--seed", "5,5"]) == 1
    assert "the edge was never found: no edge pixel near the seed" in capsys.readouterr().err


def test_tracker_follows_a_jump_after_losing_the_edge(disc_video):
    """The video restarts: the disc jumps back 120 mm nearer and 26 mm sideways, beyond the search radius and
    the disparity step allowed between frames. Both grow while the edge is lost, so the tracker takes it up
    again."""
    path, truth, rig, scene, positions = disc_video
    with VideoSource(video=str(path)) as src:
        frames = [src.read() for _ in range(8)]
    tr = EdgeTracker(rig, rim_seed(rig, scene, positions[7]), params=TrackerParams(max_jump_px=8.0))
    steps = [tr.step(f) for f in (frames[7], frames[0], frames[0], frames[0])]
    assert steps[0].ok and not steps[1].ok
    assert steps[-1].ok and steps[-1].depth_mm == pytest.approx(truth[0], rel=0.005)


def test_tracker_on_a_build_every_frame_within_0p2_percent():
    """On the misaligned build (twins rows apart) the tracker pairs on the rectified rows; 60
    frames of a disc moving in depth and sideways, every one tracked within 0.2 % of the true depth."""
    from psvs.io.params import load_rig
    from psvs.live.simulated import SimulatedSequence, disc_scene
    rig = load_rig("misaligned")
    scene = disc_scene(z_mm=700.0, radius_mm=30.0, x_mm=15.0, y_mm=-20.0)
    positions = ping_pong_positions(60, [-20.0, 12.0, -150.0], 6)
    seq = SimulatedSequence(scene, rig, positions, seed=11)
    truth = 700.0 - positions[:, 2]
    tr = EdgeTracker(rig, rim_seed(rig, scene, positions[0]))
    steps = [tr.step(seq.frame(k)) for k in range(len(positions))]
    assert all(s.ok for s in steps)
    err = np.abs(np.array([s.depth_mm for s in steps]) / truth - 1)
    assert err.max() <= 0.002, (err.max(), int(err.argmax()))
