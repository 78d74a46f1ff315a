"""The capture assistant (psvs capture): planted poses read back from rendered cards, coverage bins, the
decisions on a simulated hand-held video (save each good pose once, never a moving or cut-off card, stop when
enough), and its refusals."""
import math
import re

import numpy as np
import pytest

from psvs.calibrate.bundle import GridView
from psvs.calibrate.capture import (
    ALL_BINS,
    FIELD_BINS,
    MAX_SPEED_PX_S,
    CaptureFolder,
    CaptureParams,
    card_pose,
    card_speed_px_s,
    check_card_visible,
    detect_card,
    pose_bins,
)
from psvs.calibrate.synthetic import render_grid_shots
from psvs.io.params import load_rig
from psvs.optics.project import project_points
from psvs.simulate.scene import Pose
from psvs.simulate.textures import CircleGrid
from psvs.targets.target_file import load_target
from tests.support.cli import run
from tests.support.video import write_hand_video

CARD = CircleGrid(4, 6, 14.0, 7.0)
#: (position mm, x-y-z Euler deg, the tilt bin it is in): ry > 0 turns the card's normal toward -X (it faces
#: the image's left), rx < 0 toward -Y (it faces up).
PLANTED = [((-40.0, 20.0, 500.0), (0.0, 25.0, 4.0), "left"), ((30.0, -25.0, 820.0), (-24.0, 0.0, -3.0), "up"),
           ((10.0, 5.0, 650.0), (2.0, -3.0, 0.0), "flat"), ((-20.0, 40.0, 560.0), (0.0, -22.0, 0.0), "right")]


@pytest.fixture(scope="module")
def shots():
    """The planted poses rendered through the clear rig and through the misaligned build of it."""
    poses = [Pose.from_euler_deg(p, r) for p, r, _ in PLANTED]
    return {name: render_grid_shots(load_rig(name), CARD, poses, seed=4, supersample=1)
            for name in ("clear", "misaligned")}


@pytest.mark.parametrize("built, depth_pct, turn_deg", [("clear", 0.5, 1.5), ("misaligned", 1.5, 2.5)])
def test_card_pose_reads_the_planted_pose(shots, built, depth_pct, turn_deg):
    """Distance and turns of the card through the nominal (clear) rig. Truth: the centre's Z, and the turns of
    the card's normal toward the camera, n = -R e_z: toward +X atan2(n_x, -n_z) and toward +Y atan2(n_y, -n_z)
    (-ry and rx for a pure turn). Through the build the nominal rig is off by the build's mirror errors.
    A card facing the camera pins its turns worst: 1 deg turns its edges' distances by 0.1 % (0.13 px across the
    card at 650 mm), so a tenth of a pixel of detection bias is a degree (measured: 1.05 deg flat, 0.13 deg
    tilted; 2.1 deg and 1.1 % through the build); the bins' thresholds (15 deg, flat under 8) are far wider."""
    nominal = load_rig("clear")
    for (p, r, _), shot in zip(PLANTED, shots[built], strict=True):
        pose = card_pose(detect_card(shot.image, CARD, nominal), nominal)
        n = -shot.target2cam[:3, 2]
        assert abs(pose.distance_mm / p[2] - 1) * 100 < depth_pct
        assert math.degrees(abs(pose.turn_x_rad - math.atan2(n[0], -n[2]))) < turn_deg
        assert math.degrees(abs(pose.turn_y_rad - math.atan2(n[1], -n[2]))) < turn_deg


def test_bins_of_the_planted_poses(shots):
    """Each pose's bins: its depth third of 400-900 mm, its tilt, and the 3 x 3 cells where its centre's true
    projections land (the exact optics of the build)."""
    nominal, build = load_rig("clear"), load_rig("misaligned")
    params = CaptureParams(views=5, near_mm=400.0, far_mm=900.0)
    for (p, r, tilt), shot in zip(PLANTED, shots["misaligned"], strict=True):
        bins = pose_bins(card_pose(detect_card(shot.image, CARD, nominal), nominal), nominal, params)
        assert f"tilt:{tilt}" in bins and sum(b.startswith("tilt:") for b in bins) == 1
        third = ("near", "mid", "far")[int((p[2] - 400) // (500 / 3))]
        assert [b for b in bins if b.startswith("depth:")] == [f"depth:{third}"]
        cells = set()
        for view in ("left", "right"):
            uv, _ = project_points(np.array([p]), build, view)
            cells.add(3 * int(3 * uv[0, 1] / 480) + int(3 * uv[0, 0] / 640))
        assert {b for b in bins if b.startswith("field:")} == {f"field:{FIELD_BINS[c]}" for c in cells}
    assert len(ALL_BINS) == 17


def test_speed_of_a_card_between_detections():
    """Discs moved 3 px between frames 1/30 s apart: 90 px/s; discs no detection shares: cannot be told."""
    rng = np.random.default_rng(0)
    obj = np.column_stack([CARD.centres_mm(), np.zeros(24)])
    left, right = rng.uniform(0, 600, (24, 2)), rng.uniform(0, 400, (24, 2))
    a = GridView("a", obj, left, right)
    b = GridView("b", obj[::-1], (left + [3.0, 0.0])[::-1], (right + [0.0, 3.0])[::-1])   # listed in another order
    assert card_speed_px_s(b, a, 1 / 30) == pytest.approx(90.0, abs=1e-9)
    assert card_speed_px_s(a, a, 1 / 30) == 0.0
    assert card_speed_px_s(a, None, 1 / 30) == math.inf
    assert card_speed_px_s(GridView("c", obj[:5] + 100.0, left[:5], right[:5]), a, 1 / 30) == math.inf
    assert MAX_SPEED_PX_S == 30.0


def test_a_card_the_rig_cannot_see(tmp_path):
    """Features under the detector's smallest at the far end, or a range outside the depths the detector looks
    at: refused before any frame, saying which. 2 mm discs at 1200 mm through the default rig:
    2 x 1130 px / 1250 mm = 1.8 px < 4 px; 2 mm ChArUco markers there: 1.8 px, where OpenCV's ArUco detector
    needs a perimeter of 3 % of 640 px, a side of 4.8 px. A grid wider than the baseline (its two copies
    interleave) is fine: they are separated through the rig."""
    from psvs.simulate.textures import CharucoBoard
    default, mv = load_rig("default"), load_rig("mv1440")
    with pytest.raises(ValueError, match=r"too small to see at the far end: its 2 mm discs are 1\.8 px across at "
                                         r"1200 mm .* needs 4\.0 px"):
        check_card_visible(default, CircleGrid(4, 6, 5.0, 2.0), CaptureParams(near_mm=400, far_mm=1200))
    with pytest.raises(ValueError, match=r"its 2 mm markers are 1\.8 px across at 1200 mm .* needs 4\.8 px"):
        check_card_visible(default, CharucoBoard(5, 4, 3.0, 2.0), CaptureParams(near_mm=400, far_mm=1200))
    with pytest.raises(ValueError, match=r"the range 250-900 mm reaches outside the 300-2000 mm"):
        check_card_visible(default, CARD, CaptureParams(near_mm=250))
    check_card_visible(default, CircleGrid(4, 8, 14.0, 7.0), CaptureParams())
    check_card_visible(mv, CircleGrid(4, 5, 20.0, 10.0), CaptureParams())
    check_card_visible(mv, CARD, CaptureParams())
    for bad, message in (({"views": 2}, "views must be an integer 3-200"), ({"near_mm": 900.0}, "must be < far_mm"),
                         ({"far_mm": math.nan}, "far_mm must be a finite depth"),
                         ({"max_speed_px_s": 0.0}, "max_speed_px_s must be > 0")):
        with pytest.raises(ValueError, match=message):
            CaptureParams(**bad)


def test_the_folder_is_a_new_one(tmp_path):
    (tmp_path / "old").mkdir()
    (tmp_path / "old" / "card_00.png").write_bytes(b"x")
    with pytest.raises(ValueError, match=r"already holds card_00\.png: give a new or empty folder"):
        CaptureFolder(tmp_path / "old", b"")
    (tmp_path / "afile").write_text("x")
    with pytest.raises(ValueError, match="is a file"):
        CaptureFolder(tmp_path / "afile", b"")
    folder = CaptureFolder(tmp_path / "new" / "deeper", b"[target]\n")
    assert not (tmp_path / "new").exists()              # nothing until the first view
    assert folder.save(np.zeros((4, 6), np.uint8)) == "view_00.png"
    assert sorted(p.name for p in (tmp_path / "new" / "deeper").iterdir()) == ["target.toml", "view_00.png"]


def _saved(text: str) -> dict[int, str]:
    return {int(k): name for k, name in re.findall(r"^frame (\d+): saved (view_\d\d\.png)", text, re.M)}


@pytest.mark.slow          # ~45 frames detected (about 30 s on two free cores), after the video's renders
def test_capture_on_a_hand_held_video(capsys, hand_video, tmp_path):
    """The hand holds 11 poses (3 frames each) through the misaligned build; the assistant works through the
    nominal (clear) rig. It saves one view per pose it keeps, only of a still card wholly in view, each pose
    read within 3 % of its true distance; it says what to do in one line per event (far fewer lines than
    frames), "hold still" where the card settles; it stops once the set is enough (every bin, 9 views), and
    the folder calibrates as it is (every view passes psvs calibrate's detection, target.toml the same)."""
    out = tmp_path / "views"
    code, text, err = run(capsys, "capture", "--video", str(hand_video.path), "--target", str(hand_video.target),
                          "--rig", "clear", "-o", str(out), "--views", "9")
    assert code == 0, err
    saved = _saved(text)
    assert len(saved) >= 9 and "enough to calibrate: " in text
    plan = hand_video.plan
    assert all(plan[k].kind == "still" for k in saved)               # never a moving or cut-off card
    holds = [id(plan[k].poses[0]) for k in saved]
    assert len(set(holds)) == len(holds)                              # one view per pose
    for k, line in ((k, line) for line in text.splitlines() for k in saved if line.startswith(f"frame {k}: saved")):
        z = float(re.search(r": (\d+) mm", line)[1])
        assert abs(z / plan[k].poses[0].position_mm[2] - 1) < 0.03, line
    assert len(text.splitlines()) < 0.6 * len(plan)     # one line an event: a card held, lost, found again
    assert re.search(r"^frame \d+: hold still$", text, re.M)
    assert re.search(r"^frame \d+: (closer|farther) \(\d+-\d+ mm\)$", text, re.M)
    assert sorted(p.name for p in out.iterdir()) == ["target.toml", *sorted(saved.values())]
    assert (out / "target.toml").read_bytes() == hand_video.target.read_bytes()
    from psvs.calibrate.folder import grid_view
    from psvs.io.images import read_grey
    target = load_target(out / "target.toml")
    for name in saved.values():
        assert len(grid_view(name, read_grey(out / name, expect_size=(640, 480)), target, load_rig("clear")).left) >= 20


def test_a_video_that_ends_too_soon(capsys, tmp_path):
    """Four poses: the views are kept, and exit 1 says what is missing."""
    video = write_hand_video(tmp_path, holds=4, seed=2, hold_frames=2, move_frames=0, shared=True)
    out = tmp_path / "views"
    code, text, err = run(capsys, "capture", "--video", str(video.path), "--target", str(video.target),
                          "--rig", "clear", "-o", str(out))
    n = len(_saved(text))
    assert code == 1 and 1 <= n <= 4
    line = err.strip()
    assert len(line.splitlines()) == 1
    assert re.fullmatch(rf"psvs capture: cannot calibrate yet: {n} view\(s\) saved, missing {20 - n} more view\(s\); "
                        rf".*\(kept {n} in {re.escape(str(out))}\)", line), line
    assert len(list(out.glob("view_*.png"))) == n


def test_refusals(capsys, hand_video, tmp_path):
    """One line, exit 2, nothing written or printed: a camera that does not open, a target of an unknown kind, a card
    too small for the range, an output folder holding views, frames of another size than the rig's camera."""
    out = tmp_path / "views"
    target = str(hand_video.target)
    base = ["--target", target, "--rig", "clear", "-o", str(out)]
    unknown = tmp_path / "hex.toml"
    unknown.write_text(hand_video.target.read_text().replace("circle_grid", "hexagons"))
    small = tmp_path / "small.toml"
    small.write_text(hand_video.target.read_text().replace("diameter_mm = 7.0", "diameter_mm = 2.0"))
    old = tmp_path / "old"
    old.mkdir()
    (old / "view_00.png").write_bytes(b"x")
    keep = tmp_path / "keep"
    keep.mkdir()
    (keep / "target.toml").write_text(hand_video.target.read_text())
    cases = [(["--camera", "97", *base], "cannot open camera 97"),
             (["--video", str(hand_video.path), "--target", str(unknown), "--rig", "clear", "-o", str(out)], "kind"),
             (["--video", str(hand_video.path), "--target", str(small), "--rig", "clear", "-o", str(out),
               "--far-mm", "1200"], "too small to see at the far end"),
             (["--video", str(hand_video.path), "--target", target, "--rig", "clear", "-o", str(old)],
              "already holds view_00.png"),
             (["--video", str(hand_video.path), "--target", target, "--rig", "mv1440", "-o", str(out)],
              "frames are 640x480 px but the rig's camera is 1440x1080 px"),
             (["--video", str(hand_video.path), *base, "--views", "1"], "--views must be an integer 3-200"),
             (["--video", str(hand_video.path), *base, "--max-speed-px-s", "-1"], "--max-speed-px-s must be > 0"),
             (["--video", str(hand_video.path), "--target", str(keep / "target.toml"), "--rig", "clear", "-o",
               str(keep)], "names the input --target")]
    for argv, message in cases:
        code, text, err = run(capsys, "capture", *argv)
        assert code == 2 and message in err and len(err.strip().splitlines()) == 1, (argv, err)
        assert text == "", text                       # no "watching ..." before the refusal
        assert not out.exists()
    assert [p.name for p in old.iterdir()] == ["view_00.png"] and [p.name for p in keep.iterdir()] == ["target.toml"]
