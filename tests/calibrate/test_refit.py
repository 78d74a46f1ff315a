"""psvs refit (issue 43, item 3): a calibration's mirrors re-fitted from ordinary frames and a tare, against
planted truth (the calibration is the true build; mirrors moved since by a knock; frames rendered through the
moved build); what frames cannot give refused."""
import json
import math
import re
import tomllib

import numpy as np
import pytest

from psvs.calibrate.refit import REFIT_PARAMS, refit_rig
from psvs.calibrate.tare import MIN_TARE_SIGMA_MM, tare_plane
from psvs.errors import MeasurementError
from psvs.health.check import check_frames
from psvs.io.images import write_png
from psvs.io.params import load_rig
from psvs.simulate.builtin import textured
from psvs.simulate.render import render
from tests.support.cli import run
from tests.support.drift import DRIFTS, TARE_MM, axis_depth, frames_of, knocked
from tests.support.geometry import EXAMPLES, reconstruction_errors

#: long end-to-end runs: the README's test command runs them; .ci/latest (newest releases) does not
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def build():
    return load_rig(EXAMPLES / "rigs" / "misaligned.toml")


@pytest.mark.parametrize("name", list(DRIFTS))
def test_refit_recovers_a_planted_knock(build, name):
    """Issue 43, item 3, with the calibration exact and two tares: after the refit the twins' rows are within
    0.3 px RMS, the 3-D points within 0.4 mm (mean, after the rigid motion no image sees; 6-8 mm with the old
    calibration; the issue asks 0.15: docs/health.md has the figures), each tare surface at its distance;
    every tilt within 3 of its stated sigmas of the truth."""
    moved = knocked(build, DRIFTS[name])
    walls, tares = frames_of(moved)
    res = refit_rig(walls, build, tares)
    assert res.before.verdict == "drifted" and res.after.verdict == "healthy"
    assert res.after.row_offset_rms_px <= 0.3
    _, aligned_old, _ = reconstruction_errors(build, moved)
    _, aligned, _ = reconstruction_errors(res.rig, moved)
    assert np.mean(aligned) <= 0.4 < 5.0 < np.mean(aligned_old), (np.mean(aligned), np.mean(aligned_old))
    for t, (_, z) in zip(res.tares, tares, strict=True):
        assert abs(t.after_mm - z) <= 0.1 and t.distance_mm == z
    truth = _values_deg(moved)
    for p, (old, new, sigma) in res.change.items():
        assert abs(new - truth[p]) <= 3 * sigma + 1e-3, (p, new, truth[p], sigma)
    assert res.depth_sigma[1][1] < 1e-3 and res.unpinned


def test_the_depth_sigma_carries_the_tares_stated_distances(build):
    """A tare's distance from the optical centre O is known to a tolerance (a robot's accuracy; where a card
    calibration puts O on the axis: its depth there was 0.1 % off at 400 mm). The refit took each distance as
    exact: two tares stated 0.4 mm and 0.3 mm off their surfaces, and the depth on the axis came out beyond 3 of
    the sigmas it stated (on a card calibration 6 sigmas). Each distance's error is now an unknown with its
    sigma (--tare-sigma-mm, default 0.5): the stated depth sigma covers the error within 2 of them."""
    moved = knocked(build, DRIFTS["m3 and m4 (issue 43)"])
    walls, tares = frames_of(moved, seed=70)
    stated = [(img, z + error) for (img, z), error in zip(tares, (0.4, -0.3), strict=True)]
    exact = refit_rig(walls, build, stated, tare_sigma_mm=MIN_TARE_SIGMA_MM)    # as good as exact
    worst = max(abs(axis_depth(exact.rig, moved, z) - z) / (s * z) for z, s in exact.depth_sigma)
    assert worst > 3.0, worst
    res = refit_rig(walls, build, stated)
    for z, sigma in res.depth_sigma:
        got = axis_depth(res.rig, moved, z)
        assert abs(got - z) <= 2 * sigma * z, (z, got, sigma)
    assert all(s > s0 for (_, s), (_, s0) in zip(res.depth_sigma, exact.depth_sigma, strict=True))
    for bad in (-1.0, 0.0, 0.5 * MIN_TARE_SIGMA_MM, math.nan):
        with pytest.raises(ValueError, match="a tare's distance sigma must be a length of at least 0.01 mm"):
            refit_rig(walls, build, stated, tare_sigma_mm=bad)


def test_dense_depth_after_the_refit_is_the_undrifted_builds(build):
    """Issue 43's acceptance for dense depth, one tare: the textured scene through the knocked build, read
    with the refitted calibration, within 1 point of the undrifted build's bad share (twin-visible pixels
    off by more than 2 % of Z); with the old calibration, far worse."""
    from psvs.dense.params import DEFAULT
    from tests.support.sweep_scenes import left_truth, score
    moved = knocked(build, DRIFTS["m3 and m4 (issue 43)"])
    walls, tares = frames_of(moved, seed=60)
    res = refit_rig(walls, build, tares[:1])
    scene = textured(800.0)
    before = score(render(scene, build, seed=61).image, left_truth(scene, build), build, 400.0, 1200.0, DEFAULT)
    frame = render(scene, moved, seed=61).image
    truth = left_truth(scene, moved)
    drifted = score(frame, truth, build, 400.0, 1200.0, DEFAULT)
    after = score(frame, truth, res.rig, 400.0, 1200.0, DEFAULT)
    assert after.bad <= before.bad + 0.01 < drifted.bad - 0.1, (before.bad, after.bad, drifted.bad)


def test_one_tare_pins_the_offset_and_says_the_scale_is_not_pinned(build):
    """One tare: the surface lands at its distance, the 3-D points within 0.5 mm, and the stated depth-scale
    sigma is larger than with two tares (what no frame pinned)."""
    moved = knocked(build, DRIFTS["m2 and m1"])
    walls, tares = frames_of(moved, seed=30)
    one = refit_rig(walls, build, tares[:1])
    assert abs(one.tares[0].after_mm - tares[0][1]) <= 0.1 and abs(one.tares[0].before_mm - tares[0][1]) > 1.0
    _, aligned, _ = reconstruction_errors(one.rig, moved)
    assert np.mean(aligned) <= 0.5
    none = refit_rig(walls, build)
    assert none.tares == () and none.after.verdict == "healthy"
    assert none.scale_sigma > one.scale_sigma
    # the depth's sigma on the axis covers what each refit leaves: a point's depth through it against the truth
    for res, most in ((none, 3.0), (one, 3.0)):
        for z, sigma in res.depth_sigma:
            got = axis_depth(res.rig, moved, z)
            assert abs(got - z) <= most * sigma * z + 0.02, (len(res.tares), z, got, sigma)
    assert all(s_none > 5 * s_one for (_, s_none), (_, s_one) in zip(none.depth_sigma, one.depth_sigma, strict=True))


@pytest.mark.parametrize("f_change", [0.02, -0.01])
def test_one_tare_says_what_a_hidden_scale_would_do(build, capsys, tmp_path, f_change):
    """Trial 43: a lens 2 % longer than calibrated (a focus ring turned), refitted with one tare at 700 mm, read
    walls at 450 and 1150 mm 0.76 % short and 1.4 % long, 8 of the sigmas stated, and said nothing of it: one
    tare cannot tell a depth scale from the mirrors' turns. The refit now says what a scale s hidden in what it
    holds does to depth, s (Z / Z_tare - 1): the planted lens change's errors follow it within a fifth of s
    (an independent reading: the exact optics through the refitted rig against the truth)."""
    moved = build.replace(focal_length_mm=build.camera.focal_length_mm * (1 + f_change))
    walls, tares = frames_of(moved, seed=80)
    z_t = tares[0][1]
    res = refit_rig(walls[:1], build, tares[:1])
    for z in (450.0, 800.0, 1150.0):
        got = (axis_depth(res.rig, moved, z) - z) / z
        assert got == pytest.approx(f_change * (z / z_t - 1), abs=0.2 * abs(f_change)), (z, got)
    paths = []
    for k, img in enumerate((walls[0], tares[0][0])):
        paths.append(tmp_path / f"f{k}.png")
        write_png(paths[-1], img)
    rig_file = tmp_path / "build.toml"
    rig_file.write_text((EXAMPLES / "rigs" / "misaligned.toml").read_text())
    code, text, err = run(capsys, "refit", str(paths[0]), "--rig", str(rig_file), "--tare", str(paths[1]),
                          "--tare-mm", f"{z_t:g}", "-o", str(tmp_path / "new.toml"))
    assert code == 0, err
    line, = [x for x in text.splitlines() if x.startswith("held as calibrated: ")]
    said = [float(v) for v in re.findall(r"([-+]\d+\.\d+) % at \d+ mm", line)]
    assert said == pytest.approx([z / z_t - 1 for z in (400.0, 800.0, 1200.0)], abs=0.005), line
    assert line.endswith("beyond the sigma above: a second tare at another distance shows it")
    # two tares 20 mm apart pin the scale no better (an adversarial trial: 700 and 720 mm silenced this line
    # and the advice while the errors stayed those of one tare): said for them, about their mean distance
    from dataclasses import replace

    from psvs.calibrate.tare import SCALE_PINNED, tares_scale_sigma
    from psvs.cli.refit_cmd import summary_lines
    t = res.tares[0]
    for apart, pinned in ((20.0, False), (0.0, False), (350.0, True)):
        two = replace(res, tares=(t, replace(t, distance_mm=t.distance_mm + apart)), tare_sigma_mm=0.5)
        sigma = tares_scale_sigma([z_t, z_t + apart], 0.5)
        assert (sigma <= SCALE_PINNED) == pinned
        said = [x for x in summary_lines(two) if x.startswith("held as calibrated: ")]
        assert (said == []) == pinned, said
        if not pinned:
            effect = [float(v) for v in re.findall(r"([-+]\d+\.\d+) % at \d+ mm", said[0])]
            assert effect == pytest.approx([z / (z_t + apart / 2) - 1 for z in (400.0, 800.0, 1200.0)], abs=0.005)
            assert ("at one distance" in said[0]) == (apart == 0.0) and said[0].endswith("shows it")


def test_the_tares_pin_a_scale_as_a_straight_lines_slope():
    """tares_scale_sigma against NumPy's least-squares line: the slope's 1 sigma of readings at the tares'
    distances each known to sigma_mm; inf for one distance."""
    from psvs.calibrate.tare import tares_scale_sigma
    z = np.array([600.0, 700.0, 950.0])
    _, cov = np.polyfit(z, np.array([0.3, -0.2, 0.1]), 1, cov="unscaled")
    assert tares_scale_sigma(z, 0.5) == pytest.approx(0.5 * np.sqrt(cov[0, 0]), rel=1e-9)
    assert tares_scale_sigma([700.0, 720.0], 0.5) == pytest.approx(0.0354, abs=1e-4)
    assert tares_scale_sigma([700.0], 0.5) == tares_scale_sigma([700.0, 700.0], 0.5) == float("inf")


def test_without_a_tare_the_depth_sigma_covers_a_knock_about_the_vertical(build):
    """An adversarial trial: refit without a tare said 'depth scale: +- 0.453 %' (the baseline's sigma) while a
    wall at 1000 mm then read 982 mm, -1.8 %: the views' convergence, which no frame pins, stays at its prior.
    The depth's sigma on the axis now says so (several % without a tare) and covers the planted knock's error."""
    moved = knocked(build, DRIFTS["m3 and m4 (issue 43)"])
    walls, _ = frames_of(moved, seed=50)
    res = refit_rig(walls, build)
    for z, sigma in res.depth_sigma:
        assert sigma > 0.01 and abs(axis_depth(res.rig, moved, z) - z) <= 3 * sigma * z
    assert res.depth_sigma[-1][1] > 10 * res.scale_sigma


def _values_deg(rig) -> dict:
    out = {}
    for m in ("m1", "m2", "m3", "m4"):
        e = getattr(rig.mirrors, f"{m}_error")
        out[f"{m}_tilt_a_deg"], out[f"{m}_tilt_b_deg"] = map(math.degrees, e.tilt_rad)
        out[f"{m}_shift_mm"] = e.shift_mm
    return out


def test_an_undrifted_build_refits_to_itself(build):
    """No knock: the refit changes no tilt beyond 3 of its sigmas, the check stays healthy, and the 3-D
    points move by under 0.25 mm (mean: the tares' noise in the depth scale)."""
    walls, tares = frames_of(build, seed=20)
    res = refit_rig(walls, build, tares)
    assert res.before.verdict == "healthy" and res.after.verdict == "healthy"
    for p, (old, new, sigma) in res.change.items():
        assert abs(new - old) <= 3 * sigma + 1e-3, (p, old, new, sigma)
    _, aligned, _ = reconstruction_errors(res.rig, build)
    assert np.mean(aligned) <= 0.25


def drawn_knock(seed: int):
    """Two mirrors drawn at random, each tilted 0.02-0.2 deg out of vertical and, one time in two, as much about
    it (random signs): what issue 43 asks the tests to plant."""
    rng = np.random.default_rng(seed)
    out = []
    for m in rng.choice(["m1", "m2", "m3", "m4"], 2, replace=False):
        a = rng.uniform(0.02, 0.2) * rng.choice([-1, 1]) * (rng.random() < 0.5)
        out.append((str(m), float(a), float(rng.uniform(0.02, 0.2) * rng.choice([-1, 1])), 0.0))
    return tuple(out)


def test_refit_on_another_format_with_a_drawn_knock():
    """The 1440 x 1080 build (mv1440_misaligned), knocked by a drawn 0.05-0.17 deg (its twins 11.7 px off their
    rows, 3-D points 37 mm off): after the refit with two tares the rows within 0.3 px, the 3-D points within
    0.6 mm (0.40 measured), every tilt within 3 of its sigmas. A tile matched wrongly on a tare (the knock
    moves rows by more than the first search reaches) is left off the tare's plane, not a refusal."""
    build = load_rig("mv1440_misaligned")
    moved = knocked(build, drawn_knock(2))
    walls, tares = frames_of(moved, seed=2)
    res = refit_rig(walls, build, tares)
    assert res.before.row_offset_rms_px > 5 and res.after.row_offset_rms_px <= 0.3
    _, aligned_old, _ = reconstruction_errors(build, moved)
    _, aligned, _ = reconstruction_errors(res.rig, moved)
    assert np.mean(aligned) <= 0.6 < 20.0 < np.mean(aligned_old), (np.mean(aligned), np.mean(aligned_old))
    truth = _values_deg(moved)
    for p, (_, new, sigma) in res.change.items():
        assert abs(new - truth[p]) <= 3 * sigma + 1e-3, (p, new, truth[p], sigma)


def test_a_tare_plane_leaves_out_its_few_wrong_points_and_refuses_many():
    """check_flat on a wall at 700 mm (0.1 px of noise): 5 % of its points 5-80 px off (wrong matches) are left
    out, and the plane through the rest is the wall's; 30 % off, it is not one plane."""
    from psvs.calibrate.tare import check_flat, disparity_per_mm, flat_plane
    rig = load_rig("misaligned")
    rng = np.random.default_rng(3)
    xy = rng.uniform(-200, 200, (300, 2))
    z = 700 + 0.05 * xy[:, 0] + rng.normal(0, 0.1, 300) / disparity_per_mm(rig, 700.0)
    for share, ok in ((0.05, True), (0.3, False)):
        bad = rng.random(300) < share
        zz = z + bad * rng.uniform(5, 80, 300) * rng.choice([-1, 1], 300) / disparity_per_mm(rig, 700.0)
        pts = np.column_stack([xy, zz])
        if ok:
            on = check_flat(pts, rig, 0.1, "the tare")
            assert (on == ~bad).all()
            coef = flat_plane(pts, rig)[0]
            assert abs(coef[0] - 700) < 0.2 and abs(coef[1] - 0.05) < 1e-3
        else:
            with pytest.raises(MeasurementError, match="% of its points lie on one plane"):
                check_flat(pts, rig, 0.1, "the tare")


def test_a_bent_tare_says_its_scatter_and_the_stated_distance():
    """Issue 41's trial: a tare stated at 500 mm (it stood at 700) was refused as 'not flat: 100 % of its points
    lie on one plane (a tare needs 80 %)', a reason that contradicts itself. All points on the (bent) surface,
    scattering 1 px about a plane: the message says the scatter and its limit, and the hint it is given."""
    from psvs.calibrate.tare import check_flat, disparity_per_mm
    rig = load_rig("misaligned")
    rng = np.random.default_rng(4)
    xy = rng.uniform(-200, 200, (300, 2))
    bend = (xy[:, 0] / 200) ** 2 - 1 / 3                          # a bowl: every point on one smooth surface
    z = 700 + 2.0 * bend / disparity_per_mm(rig, 700.0)
    with pytest.raises(MeasurementError, match=r"^the tare is not flat: its points scatter \S+ mm \(\S+ px of "
                                               r"disparity\) about their plane, a flat surface within 0\.50 px; .*, "
                                               r"or it stands elsewhere$"):
        check_flat(np.column_stack([xy, z]), rig, 0.1, "the tare", ", or it stands elsewhere")


def test_the_tare_plane_is_the_least_squares_plane():
    """tare_plane against numpy's polyfit-free closed form: points on Z = 700 + 0.01 X - 0.02 Y with noise."""
    rng = np.random.default_rng(1)
    xy = rng.uniform(-200, 200, (400, 2))
    z = 700 + 0.01 * xy[:, 0] - 0.02 * xy[:, 1] + rng.normal(0, 0.1, 400)
    coef, rms = tare_plane(np.column_stack([xy, z]))
    A = np.column_stack([np.ones(400), xy])
    expect = np.linalg.solve(A.T @ A, A.T @ z)
    assert np.allclose(coef, expect, atol=1e-9) and abs(rms - 0.1) < 0.01
    fixed, _ = tare_plane(np.column_stack([xy, z]), 690.0)
    # the intercept held 10 mm off: the slopes take up what the sample's mean X, Y carry of it
    assert fixed[0] == 690.0 and abs(fixed[1] - 0.01) < 3e-3


def test_frames_without_texture_are_refused(build):
    blank = np.full((480, 640), 90, np.uint8)
    with pytest.raises(MeasurementError, match="cannot refit: the frames"):
        refit_rig([blank, blank], build)
    walls, _ = frames_of(build, seed=50)
    with pytest.raises(MeasurementError, match="cannot refit: tare 1"):
        refit_rig(walls, build, [(blank, 700.0)])


def test_a_tare_that_is_not_flat_is_refused(build):
    """The textured scene (a panel, a box, a ball before a backdrop) as the tare: refused, not a depth."""
    moved = knocked(build, DRIFTS["m2 and m1"])
    walls, _ = frames_of(moved)
    scene = render(textured(800.0), moved, seed=4).image
    with pytest.raises(MeasurementError, match="not flat"):
        refit_rig(walls, build, [(scene, 800.0)])


def test_a_tare_needs_its_distance_in_the_working_range(build):
    img = np.zeros((480, 640), np.uint8)
    with pytest.raises(ValueError, match="working range 400-1200 mm, got 2000"):
        refit_rig([img], build, [(img, 2000.0)])


def test_the_command_writes_a_rig_and_a_record_it_reads_back(capsys, tmp_path, build):
    """psvs refit end to end: the rig file read back (tomllib) holds the refit's tilts, the record (json)
    each change with its sigma and the rows before and after; the refitted rig passes psvs check."""
    moved = knocked(build, DRIFTS["m3 and m4 (issue 43)"])
    walls, tares = frames_of(moved, seed=40)
    paths = []
    for k, img in enumerate(walls + [img for img, _ in tares]):
        paths.append(tmp_path / f"f{k}.png")
        write_png(paths[-1], img)
    out = tmp_path / "new.toml"
    code, text, err = run(capsys, "refit", *map(str, paths[:3]), "--rig", str(EXAMPLES / "rigs" / "misaligned.toml"),
                          "--tare", str(paths[3]), "--tare-mm", str(TARE_MM[0]), "--tare", str(paths[4]),
                          "--tare-mm", str(TARE_MM[1]), "-o", str(out))
    assert code == 0, err
    assert "rows before: drifted" in text and "after the refit: healthy" in text
    record = json.loads((tmp_path / "new.refit.json").read_text())
    data = tomllib.loads(out.read_text())
    for m in ("m1", "m2", "m3", "m4"):
        tilt = data["mirrors"][m]["tilt_deg"]
        assert tilt[0] == pytest.approx(record["change"][f"{m}_tilt_a_deg"]["new"], abs=1e-5)
        assert tilt[1] == pytest.approx(record["change"][f"{m}_tilt_b_deg"]["new"], abs=1e-5)
    assert set(record["change"]) == {p[:-4] + "_deg" if p.endswith("_rad") else p for p in REFIT_PARAMS}
    assert all(v["sigma"] > 0 for v in record["change"].values())
    assert record["rows_before"]["verdict"] == "drifted" and record["rows_after"]["row_offset_rms_px"] <= 0.3
    assert [t["distance_mm"] for t in record["tares"]] == list(TARE_MM)
    assert all(abs(t["after_mm"] - t["distance_mm"]) <= 0.1 for t in record["tares"])
    said = text.split("depth on the axis: ")[1].split(" (1 sigma)")[0].split(", ")
    assert [(float(w.split()[4]), float(w.split()[1]) / 100) for w in said] == [
        (d["z_mm"], pytest.approx(d["sigma"], abs=5e-5)) for d in record["depth_sigma"]]
    assert [d["z_mm"] for d in record["depth_sigma"]] == [400.0, 800.0, 1200.0]
    assert record["tare_sigma_mm"] == 0.5 and "tare 1: the surface at 600 +- 0.5 mm read" in text
    assert "from what no frame pinned and the tares' distances" in text
    assert data["calibration"]["kinds"].startswith("refit from 3 frame(s), tare(s) at 600, 950 mm")
    again = check_frames(walls, load_rig(out))
    assert again.verdict == "healthy", again.reason
    # --adjust alone: the screw turns for the refitted build (as psvs adjust on it), no file
    code, text, err = run(capsys, "refit", *map(str, paths[:3]), "--rig", str(EXAMPLES / "rigs" / "misaligned.toml"),
                          "--adjust")
    assert code == 0, err
    guide = text[text.index("alignment guide:"):]
    assert "M3" in guide and "twins' row offset after the turns (predicted)" in guide and "wrote" not in text


def test_the_command_refuses_what_it_cannot_do(capsys, tmp_path):
    rig = str(EXAMPLES / "rigs" / "misaligned.toml")
    blank = tmp_path / "blank.png"
    write_png(blank, np.full((480, 640), 90, np.uint8))
    code, _, err = run(capsys, "refit", str(blank), "--rig", rig)
    assert code == 2 and "give -o NEW.toml" in err
    code, _, err = run(capsys, "refit", str(blank), "--rig", rig, "-o", str(tmp_path / "n.toml"), "--tare-mm", "700")
    assert code == 2 and "each tare needs both --tare IMAGE and --tare-mm Z: 0 image(s), 1 distance(s)" in err
    for bad in ("-0.1", "nan", "0", "0.005"):      # (trial 43: 0 was taken, the depth stated as if exact)
        code, _, err = run(capsys, "refit", str(blank), "--rig", rig, "-o", str(tmp_path / "n.toml"),
                           "--tare-sigma-mm", bad)
        assert code == 2 and err.count("\n") == 1, err
        assert f"--tare-sigma-mm must be a length of at least 0.01 mm (no surface's distance from the optical " \
               f"centre is known exactly), got {float(bad):g}" in err, err
    code, _, err = run(capsys, "refit", str(blank), "--rig", rig, "-o", str(tmp_path / "n.toml"))
    assert code == 1 and "cannot refit" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "n.toml").exists() and not (tmp_path / "n.refit.json").exists()
    # the record's place a folder: refused before the work (the blank frame would be refused after it, exit 1)
    (tmp_path / "n.refit.json").mkdir()
    code, _, err = run(capsys, "refit", str(blank), "--rig", rig, "-o", str(tmp_path / "n.toml"))
    assert code == 2 and f"output {tmp_path / 'n.refit.json'} is a folder, not a file" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["blank.png", "n.refit.json"]


def test_the_same_tare_twice_is_one_image_and_refused(build):
    """An adversarial trial (2026-12-05): the same tare given twice counted as two (364 pairs for 182, the depth
    sigma narrowed); an image stated at two distances is no tare. Refused before any work, naming both."""
    rng = np.random.default_rng(3)
    img = rng.integers(0, 255, (480, 640), dtype=np.uint8)
    other = rng.integers(0, 255, (480, 640), dtype=np.uint8)
    for distances in ((700.0, 700.0), (700.0, 900.0)):
        with pytest.raises(ValueError, match=r"^tare 3 is the same image as tare 1: one image of a surface is one "
                                             r"tare, however often it is given"):
            refit_rig([other], build, [(img, distances[0]), (other, 800.0), (img.copy(), distances[1])])


def test_a_tare_taken_before_the_knock_is_named(build):
    """An adversarial trial (2026-12-05): frames after the knock, a tare taken before it (its twins on the old
    rows). The refit was refused as 'what moved is more than the mirrors' tilts; calibrate again' (or as a turn
    of 1.09 deg), though the frames refit cleanly with a tare of their own state. The tare's own twins are now
    checked under the frames' own rows' refit: the refusal names the tare."""
    moved = knocked(build, DRIFTS["m3 and m4 (issue 43)"])
    walls, _ = frames_of(moved, seed=90)
    _, old_tares = frames_of(build, seed=90)
    for tares in (old_tares[:1], old_tares[1:]):
        with pytest.raises(MeasurementError, match=r"^tare 1 shows another state of the rig than the frames: under "
                                                   r"their refit its twins stand off their rows \(the twins stand off "
                                                   r"their rows: .*\); was it taken before a knock\?"):
            refit_rig(walls, build, tares)


def test_a_tare_stated_at_the_wrong_distance_is_refused(build):
    """Issue 41's trial: the second tare stated 50 mm beyond where its wall was wanted every mirror turned about
    4 deg about the vertical (a blocked layout every command then refused). A change beyond what a knock does
    (1 deg) is refused, naming the tares; nothing is returned."""
    moved = knocked(build, DRIFTS["m3 and m4 (issue 43)"])
    walls, tares = frames_of(moved, seed=70)
    wrong = [tares[0], (tares[1][0], tares[1][1] + 50.0)]
    with pytest.raises(MeasurementError, match=r"^the refit would turn m\d_tilt_a_deg by [+-]\d+\.\d+ deg, more "
                                               r"than a knock does \(at most 1 deg\) \(the tares at 600, 1000 mm"):
        refit_rig(walls, build, wrong)


@pytest.mark.parametrize("error_mm", [-100.0, -44.0, 25.0, 100.0])
def test_a_tare_whose_distance_the_rows_contradict_is_refused(build, error_mm):
    """Adversarial trials (issue 41): a wall at 700 mm stated as 800 was taken, the refit `healthy` at 0.26 px
    (0.02 with the truth), and the new rig read a 650 mm wall at 736 mm; a tare at 600 mm stated as 556 (taped
    from the rig's front, not from O) was taken with depth 5-13 % off, stated to 0.1-0.3 %. The turns a wrongly
    stated distance asks fit the frames' twins worse than the calibration's turns by more than chance: refused,
    naming the tare and the figures (three walls: a tare 20 mm off gave a chi-square of 13-65, the right ones
    -7.3 to +0.5, chance 10.8)."""
    moved = knocked(build, DRIFTS["m3 and m4 (issue 43)"])
    walls, tares = frames_of(moved, seed=80)
    image, z = tares[0]
    with pytest.raises(MeasurementError, match=rf"^the tares disagree with the frames: the turns their depth asks "
                                               rf"put the twins \d\.\d\d \+- \d\.\d\d px off their rows, \d\.\d\d \+- "
                                               rf"\d\.\d\d px without them, a fit worse by a chi-square of \d+\.\d "
                                               rf"over the frames' \d+ tiles where chance gives up to 10\.8 \(the "
                                               rf"tares at {z + error_mm:g} mm: "):
        refit_rig(walls, build, [(image, z + error_mm)])


def test_a_turn_beyond_the_prior_that_no_tare_pins_is_refused(build):
    """An adversarial trial (2026-12-06): M1 of the misaligned build turned 0.8 deg about the vertical (under the
    refit's 1 deg limit), refit with a tare at 600 mm: exit 0, the four turns changed 0.21 deg each, depth
    stated to 0.26 % at 1200 mm and a wall at 1150 mm 1.05 % off through it. The pinned change stands 4 of the
    prior's sigmas out while combinations no tare pins are held to the prior: refused. (With both tares the
    second is refused as bent: the old rig puts it past the range.) The issue-43 knock (above) passes the same
    test."""
    moved = knocked(build, (("m1", 0.8, 0.0, 0.0),))
    walls, tares = frames_of(moved)
    with pytest.raises(MeasurementError, match=r"to change by 0.\d\d deg in all, [4-9].\d times what a knock "
                                               r"does .* no tare pins are held to that"):
        refit_rig(walls, build, tares[:1])
