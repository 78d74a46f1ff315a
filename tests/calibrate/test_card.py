"""Calibration of a misaligned build from a hand-held circle-grid card: planted truth.

The images are rendered through examples/rigs/misaligned.toml (mirrors 0.1-0.3 deg and up to 0.8 mm off,
the box turned, k1 = -0.2, k2 = 0.45 with tangential terms, f +1 %, principal point 5 px off); calibration starts from
the nominal design (examples/rigs/clear.toml without mirror extents)."""
import csv
import math
import re
import tomllib
from pathlib import Path

import cv2
import numpy as np
import pytest

from psvs.calibrate.bundle import ASPECT_SCORE_LIMIT
from psvs.calibrate.folder import calibrate_folder
from psvs.calibrate.report import vertical_disagreement
from psvs.calibrate.synthetic import random_poses, render_grid_shots
from psvs.cli.main import main
from psvs.io.images import write_png
from psvs.io.params import load_rig
from psvs.simulate.textures import CircleGrid
from psvs.targets.target_file import dumps_target, load_target
from tests.reference_build import Box, Lens, ReferenceBuild
from tests.support.cli import run
from tests.support.geometry import reconstruction_errors

#: long end-to-end runs: the README's test command runs them; .ci/latest (newest releases) does not
pytestmark = pytest.mark.slow

RIGS = Path(__file__).resolve().parents[2] / "examples" / "rigs"
CARD = CircleGrid(4, 6, 14.0, 7.0)


def nominal():
    return load_rig(RIGS / "clear.toml").with_extents({k: None for k in ("m1", "m2", "m3", "m4")})


@pytest.fixture(scope="module")
def card_dir(tmp_path_factory):
    """16 card views at 450-1000 mm (tilted up to 25 deg), a blank frame and a frame without the card."""
    folder = tmp_path_factory.mktemp("card")
    true = load_rig(RIGS / "misaligned.toml")
    poses = random_poses(true, CARD, 16, seed=3)
    for k, shot in enumerate(render_grid_shots(true, CARD, poses, seed=40)):
        write_png(folder / f"card_{k:02d}.png", shot.image)
    write_png(folder / "blank.png", np.full((480, 640), 30, np.uint8))
    junk = np.full((480, 640), 40, np.uint8)
    cv2.circle(junk, (200, 200), 10, 200, -1)
    write_png(folder / "lamp.png", junk)
    (folder / "target.toml").write_text(dumps_target(CARD))
    return folder, true


@pytest.fixture(scope="module")
def calibrated(card_dir):
    folder, _ = card_dir
    return calibrate_folder(folder, nominal())


def test_reprojection_and_reconstruction(calibrated, card_dir):
    """Acceptance: RMS <= 0.05 px. True correspondences over 400-1200 mm, triangulated with the calibrated
    rig: what no card view can fix (docs/calibration.md, "What a card cannot see") is (a) where frame C
    sits behind the mirrors, a rigid motion of the whole reconstruction, and (b) its scale, through the
    focal length (a narrow lens sees f and distance only together; +-0.1-0.2 % with cards tilted 25 deg).
    Up to a similarity the reconstruction is within 0.35 mm; up to a rigid motion within 0.3 % of depth;
    in frame C itself the error is reported in docs, not hidden."""
    res = calibrated
    b = res.bundle
    assert b.success and b.rms_px <= 0.05
    assert max(b.rms_by_view.values()) <= 0.05 and max(b.rms_by_image.values()) <= 0.1
    raw, aligned, pts = reconstruction_errors(res.rig, card_dir[1])
    assert np.mean(aligned / pts[:, 2]) <= 3e-3
    f_err = b.values["focal_length_mm"] / card_dir[1].camera.focal_length_mm - 1
    assert abs(f_err) < 3 * b.sigma["focal_length_mm"] / card_dir[1].camera.focal_length_mm
    scaled, aligned_s, _ = reconstruction_errors(res.rig, card_dir[1], scale=1 / (1 + f_err))
    assert np.mean(aligned_s) <= 0.35


def test_the_lens_is_recovered(calibrated, card_dir):
    """The lens terms the card sees, within 4 sigma (and sigma small): planted k1 -0.2, p1 1.2e-3,
    p2 -0.9e-3, f 11.413 mm; the plate 3 mm."""
    true = card_dir[1]
    v, s = calibrated.bundle.values, calibrated.bundle.sigma
    k1, k2, p1, p2, k3 = true.camera.distortion
    for name, want, max_sigma in (("k1", k1, 0.01), ("p1", p1, 5e-4), ("p2", p2, 5e-4),
                                  ("focal_length_mm", true.camera.focal_length_mm, 0.03),
                                  ("plate_thickness_mm", 3.0, 0.3)):
        assert s[name] < max_sigma, name
        assert abs(v[name] - want) < 4 * s[name] + 1e-9, (name, v[name], want, s[name])


def test_square_pixels_stay_square(calibrated):
    """The build's pixels are square, as the start rig says: the score test for freeing the pixel's aspect
    stays under chi-square's 99.9 % point (tests/calibrate/test_aspect.py frees it on pixels 0.5-1 % off), so
    the calibrated pitch is the start's to the bit and the aspect is not listed as held by a prior."""
    b = calibrated.bundle
    assert b.aspect_score is not None and 0 <= b.aspect_score <= ASPECT_SCORE_LIMIT
    assert calibrated.rig.camera.pixel_pitch_mm == nominal().camera.pixel_pitch_mm
    assert "pixel_aspect" not in b.held_by_prior and b.sigma["pixel_aspect"] == 0.0


def test_skipped_images_say_why(calibrated):
    assert set(calibrated.skipped) == {"blank.png", "lamp.png"}
    assert "found 0 disc(s), expected 48" in calibrated.skipped["blank.png"]
    assert re.search(r"found \d+ disc\(s\), expected 48", calibrated.skipped["lamp.png"])
    assert len(calibrated.used) == 16 and set(calibrated.used.values()) == {"grid"}


def test_vertical_disagreement_map_against_the_reference(card_dir):
    """The report's map: where the twin of a left-view pixel lies, rows off, at 700 mm, against the
    independent reference build (its left ray to 700 mm, projected into its right view)."""
    true = card_dir[1]
    c = true.camera
    errors = {n: (*true.mirrors.error(n).tilt_rad, true.mirrors.error(n).shift_mm) for n in ("m1", "m2", "m3", "m4")}
    ref = ReferenceBuild(Lens(f=c.focal_length_mm, centre=c.principal_point_px, dist=c.distortion),
                         Box(c1=22.0, c2=44.0), errors=errors, box_rotvec=true.mirrors.box_rotation_rad)
    u, v, dv = vertical_disagreement(true, 700.0, step_px=80)
    for (uu, vv, d) in zip(u.ravel(), v.ravel(), dv.ravel(), strict=True):
        if not np.isfinite(d):
            continue
        o, direction = ref.left_line(uu, vv)
        p = o + (700.0 - o[2]) / direction[2] * direction
        assert ref.project_right(p[None, :])[0, 1] - vv == pytest.approx(d, abs=1e-4)
    assert np.nanmax(np.abs(dv)) > 3.0          # this build's twins are rows apart


def test_cli_writes_a_rig_that_reads_back_and_a_report(capsys, card_dir, tmp_path):
    """The rig file is the nominal file with the calibrated values (its comments kept: one planted beside
    focal_length_mm), read back by tomllib; --report creates its folder (parents too) and residuals.csv holds
    the residuals whose RMS the terminal and the rig file's [calibration] table report."""
    folder, _ = card_dir
    out = tmp_path / "rig.toml"
    mine = "# my lens: 11.3 mm on the label"
    nominal = tmp_path / "nominal.toml"
    nominal.write_text((RIGS / "clear.toml").read_text().replace("[camera]\n", f"[camera]\n{mine}\n"))
    report = tmp_path / "new" / "report"
    code, text, err = run(capsys, "calibrate", str(folder), "--rig", str(nominal), "-o", str(out),
                          "--report", str(report))
    assert code == 0, err
    assert "skipped blank.png: found 0 disc(s)" in err
    # how the fit ended, in its own words (SciPy's "`ftol` termination condition is satisfied." was printed)
    assert re.search(r"^bundle adjustment converged: the (cost|gradient|parameters) .+ \(\d+ evaluations\)$",
                     text, re.M), text
    assert "termination" not in text + err
    found = re.search(r"reprojection RMS ([0-9.]+) px \(left view ([0-9.]+), right view ([0-9.]+)\)", text)
    rms = float(found[1])
    assert rms <= 0.05
    assert len(re.findall(r"^  card_\d\d\.png\s+[0-9.]+ px$", text, re.M)) == 16
    printed = {m[0]: float(m[1]) for m in re.findall(r"^  (\w+)\s+(-?[0-9.]+)  \+-", text, re.M)}
    data = tomllib.loads(out.read_text())
    rig = load_rig(out)
    assert data["camera"]["distortion"][0] == pytest.approx(printed["k1"], abs=1e-5)
    assert rig.camera.distortion[0] == pytest.approx(printed["k1"], abs=1e-5)
    assert data["mirrors"]["m2"]["tilt_deg"][1] == pytest.approx(printed["m2_tilt_b_deg"], abs=1e-5)
    assert math.degrees(rig.mirrors.error("m3").tilt_rad[0]) == pytest.approx(printed["m3_tilt_a_deg"], abs=1e-5)
    assert data["camera"]["focal_length_mm"] == pytest.approx(printed["focal_length_mm"], abs=1e-5)
    # the nominal file's comments and layout: the planted line above focal_length_mm, the header, inline arrays
    lines = out.read_text().splitlines()
    assert lines[lines.index(mine) + 1].startswith("focal_length_mm = ")
    assert lines[:6] == nominal.read_text().splitlines()[:6]
    assert all(line.endswith("]") for line in lines if " = [" in line and not line.startswith("#"))
    assert data["mirrors"]["m1"]["along_mm"] == [-6.866250675245926, 14.39631001284942]   # the extents stay
    assert report.is_dir()
    for name, size in (("residuals.png", (620, 800)), ("vertical_disagreement.png", (620, 800))):
        img = cv2.imread(str(report / name))
        assert img is not None and img.shape[:2] == size
        assert (np.abs(img.astype(int) - 255).sum(axis=2) > 60).mean() > 0.02   # drawn, not blank
    with (report / "residuals.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert {r["image"] for r in rows} == {f"card_{k:02d}.png" for k in range(16)}
    cal = data["calibration"]
    assert cal["images"] == 16 and cal["kinds"] == "16 grid"
    for view, key, k in (("left", "rms_left_px", 2), ("right", "rms_right_px", 3)):
        r = np.array([[float(x["du_px"]), float(x["dv_px"])] for x in rows if x["view"] == view])
        assert len(r) > 16 * 8
        assert np.sqrt(np.mean(r ** 2)) == pytest.approx(cal[key], rel=1e-12)
        assert np.sqrt(np.mean(r ** 2)) == pytest.approx(float(found[k]), abs=5e-5)
    all_r = np.array([[float(x["du_px"]), float(x["dv_px"])] for x in rows])
    assert np.sqrt(np.mean(all_r ** 2)) == pytest.approx(cal["rms_px"], rel=1e-12)


def test_target_file_errors(tmp_path):
    good = dumps_target(CARD)
    assert load_target(_write(tmp_path, good)) == CARD
    for text, message in ((good.replace('kind = "circle_grid"', 'kind = "chessboard"'),
                           r"target\.kind must be one of circle_grid, asymmetric_circle_grid, charuco, "
                           r"got 'chessboard'"),
                          (good.replace("rows = 4\n", ""), r"missing key target\.rows"),
                          (good + "colour = 1\n", r"unknown key target\.colour"),
                          (good.replace("diameter_mm = 7.0", "diameter_mm = 20.0"),
                           r"diameter_mm must be < spacing_mm"),
                          (good.replace("rows = 4", "rows = 1000000000"),
                           r"target\.rows must be a whole number <= 200, got 1000000000"),
                          ("[card]\nrows = 3\n", r"expected one table \[target\]")):
        with pytest.raises(ValueError, match=message):
            load_target(_write(tmp_path, text))


def _write(tmp_path, text):
    p = tmp_path / "target.toml"
    p.write_text(text)
    return p


def test_cli_bad_folders(capsys, card_dir, tmp_path):
    """One line, exit 2, and an earlier rig file left as it was."""
    out = tmp_path / "rig.toml"
    out.write_text("keep")
    code, _, err = run(capsys, "calibrate", str(tmp_path / "none"), "--rig", str(RIGS / "clear.toml"), "-o", str(out))
    assert code == 2 and "calibration folder not found" in err and len(err.strip().splitlines()) == 1
    few = tmp_path / "few"
    few.mkdir()
    (few / "target.toml").write_text(dumps_target(CARD))
    for name in ("card_00.png", "card_01.png"):
        (few / name).write_bytes((card_dir[0] / name).read_bytes())
    code, _, err = run(capsys, "calibrate", str(few), "--rig", str(RIGS / "clear.toml"), "-o", str(out))
    assert code == 2 and "calibration needs at least 3 usable images, got 2" in err
    (few / "target.toml").write_text(dumps_target(CARD).replace("rows = 4", "rows = 5"))
    code, _, err = run(capsys, "calibrate", str(few), "--rig", str(RIGS / "clear.toml"), "-o", str(out))
    # a 4x6 card read as part of a 5x6 one fits it at two places: each view's points are not told apart
    assert code == 2 and "24 points found, but which of the card's they are is not certain" in err
    assert out.read_text() == "keep"
    # a report "folder" that is a file is refused before any work, in one line
    code, _, err = run(capsys, "calibrate", str(card_dir[0]), "--rig", "clear", "-o", str(out), "--report", str(out))
    assert code == 2 and f"report folder {out} is a file" in err and len(err.strip().splitlines()) == 1
    assert out.read_text() == "keep"
    # one pose photographed again (one pixel differs: not byte-identical) adds no view: an adversarial trial's
    # 12 such copies calibrated to a focal length 9 sigma off and a rig whose glass blocks a view
    same = tmp_path / "same"
    same.mkdir()
    (same / "target.toml").write_text(dumps_target(CARD))
    for k in range(4):
        (same / f"card_{k:02d}.png").write_bytes((card_dir[0] / f"card_{k:02d}.png").read_bytes())
    again = cv2.imread(str(card_dir[0] / "card_02.png"), cv2.IMREAD_UNCHANGED)
    again[5, 5] ^= 1
    cv2.imwrite(str(same / "card_09.png"), again)
    code, _, err = run(capsys, "calibrate", str(same), "--rig", str(RIGS / "clear.toml"), "-o", str(out))
    assert code == 2 and "card_02.png and card_09.png show the card in one pose (its points 0.00 px apart" in err
    assert len(err.strip().splitlines()) == 1 and out.read_text() == "keep"


def test_views_a_far_start_leaves_unexplained_are_kept(capsys, tmp_path):
    """The README's run: 16 card views of the misaligned build (its lens k2 = 0.45), calibrated from the clear
    design. The first adjustment from the design settled with 7 of them unexplained (1.1-2.2 px) and they
    were skipped; adjusted again from where the other 9 put the rig, all 16 fit within 0.05 px."""
    from tests.support.cli import run
    code, _, err = run(capsys, "card-views", str(tmp_path / "cards"), "--rig", "misaligned", "--views", "16")
    assert code == 0, err
    res = calibrate_folder(tmp_path / "cards", load_rig(RIGS / "clear.toml"))
    assert res.skipped == {} and len(res.used) == 16
    assert res.bundle.rms_px <= 0.05 and max(res.bundle.rms_by_image.values()) <= 0.1


def test_the_self_check_on_the_card_calibration(calibrated, card_dir):
    """Issue 43's acceptance on this build as psvs calibrated it from its card views: frames of the undrifted
    build are healthy (<= 0.5 px RMS); after M3 leans 0.06 deg and M4 moves 0.03 deg out of vertical and
    0.05 deg about it, drifted, the figure within 40 % of the twins' true offset under the old calibration
    (the optics: each judged tile's left-grid pixel traced through the moved build to the wall and back)."""
    from psvs.dense.rig_cache import rectification
    from psvs.health.check import check_frames
    from psvs.health.explain import tilted
    from psvs.optics.project import project_points
    from psvs.optics.trace import trace_pixels
    from psvs.simulate.builtin import regulated_light
    from psvs.simulate.render import render
    from psvs.simulate.scene import Scene
    from psvs.simulate.textures import Noise
    cal, true = calibrated.rig, card_dir[1]
    z = 760.0
    wall = Scene((), regulated_light(z), z, Noise(scale_mm=1.5, seed=11), "wall")
    same = check_frames([render(wall, true, seed=5).image], cal)
    assert same.verdict == "healthy" and same.row_offset_rms_px <= 0.5, same.reason
    moved = tilted(tilted(true, "m3", 0.0, math.radians(0.06)), "m4", math.radians(0.05), math.radians(0.03))
    c = check_frames([render(wall, moved, seed=5).image], cal)
    rect = rectification(cal, 400.0, 1200.0)
    rays = trace_pixels(rect.to_complex(c.centre_px, "left"), moved, "left")
    p = rays.origins_mm + ((z - rays.origins_mm[:, 2]) / rays.dirs[:, 2])[:, None] * rays.dirs
    right, ok = project_points(p, moved, "right")
    truth = rect.to_rectified(right[ok], "right")[:, 1] - c.centre_px[ok, 1]
    true_rms = float(np.sqrt(np.mean(truth ** 2)))
    assert c.verdict == "drifted", c.reason
    assert abs(c.row_offset_rms_px - true_rms) <= 0.4 * true_rms, (c.row_offset_rms_px, true_rms)


def test_refit_on_the_card_calibration(calibrated, card_dir):
    """Issue 43's own case, end to end: the build as psvs calibrated it from its card views, then M3 leaned
    0.06 deg and M4 moved 0.03 deg out of vertical and 0.05 deg about it; refit from three walls and two tares
    (their distances from the true optical centre, which the card calibration places 0.4-0.5 mm off on the
    axis). The rows come back; the 3-D points come back from 8 mm to under 0.5 mm (measured 0.11-0.47 mm over
    three seeds; issue 43 asks 0.15: docs/health.md); and the depth on the axis within 2 of its stated sigmas
    (the tares' distances taken as exact had stated sigmas 4-6 times too small here)."""
    from psvs.calibrate.refit import refit_rig
    from tests.support.drift import DRIFTS, axis_depth, frames_of, knocked
    cal, true = calibrated.rig, card_dir[1]
    moved = knocked(true, DRIFTS["m3 and m4 (issue 43)"])
    walls, tares = frames_of(moved, seed=20)
    res = refit_rig(walls, cal, tares)
    assert res.before.verdict == "drifted" and res.after.row_offset_rms_px <= 0.3, res.after.reason
    _, old, _ = reconstruction_errors(cal, moved)
    _, new, _ = reconstruction_errors(res.rig, moved)
    assert np.mean(new) <= 0.5 < 5.0 < np.mean(old), (np.mean(new), np.mean(old))
    for z, sigma in res.depth_sigma:
        got = axis_depth(res.rig, moved, z)
        assert abs(got - z) <= 2 * sigma * z, (z, got, sigma)


@pytest.fixture(scope="module")
def hand_views(tmp_path_factory):
    """16 views of the misaligned build as `psvs card-views` makes them (the adversarial trial's, seed 1)."""
    folder = tmp_path_factory.mktemp("hand") / "views"
    code = main(["card-views", str(folder), "--rig", "misaligned", "--views", "16", "--seed", "1"])
    assert code == 0
    return folder


@pytest.mark.parametrize("turn", ["rotated 180 deg", "mirrored"])
def test_card_views_turned_or_mirrored_are_refused(hand_views, turn, tmp_path, capsys):
    """An adversarial trial: ten of these views turned by 180 degrees (or mirrored left-right) calibrated at
    RMS 0.20 px with every value plausible (f 11.29 +- 0.002 mm, 68 sigma off) and exit 0; the views' own
    detections carry 0.026 px of noise. Now refused (exit 1) naming both figures, nothing written. (Other
    views, mirrored, can fit at their noise: a mirror image of a PSVS is one with its paths swapped;
    docs/right-or-refuse.md.)"""
    bad = tmp_path / "turned"
    bad.mkdir()
    (bad / "target.toml").write_text((hand_views / "target.toml").read_text())
    for path in sorted(hand_views.glob("card_*.png"))[:10]:
        img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        write_png(bad / path.name, img[::-1, ::-1] if turn == "rotated 180 deg" else img[:, ::-1])
    out = tmp_path / "rig.toml"
    code, _, err = run(capsys, "calibrate", str(bad), "--rig", "clear", "-o", str(out))
    assert code == 1 and not out.exists(), err
    assert re.search(r"does not fit its views: reprojection RMS 0\.[12]\d\d px against the detections' own noise "
                     r"0\.0[1-4]\d px", err), err
    assert len(err.strip().splitlines()) == 1
    # the views as taken calibrate
    code, _, err = run(capsys, "calibrate", str(hand_views), "--rig", "clear", "-o", str(out))
    assert code == 0 and out.exists(), err
