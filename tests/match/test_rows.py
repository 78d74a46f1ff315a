"""Twins on the rig's rows (psvs.match.rows): a pair whose twin lines up decisively better some rows off
is refused, and an image whose pairs all do is refused as a whole ("the rig does not fit this image"),
never measured. Planted: drawn outlines with their twin shifted by known rows; renders of Fig. 5b with the
right view moved by k rows (as a knocked mirror moves it)."""
import numpy as np
import pytest

from psvs import default_rig
from psvs.errors import MeasurementError
from psvs.io.images import write_png
from psvs.io.params import load_rig
from psvs.match.correspondence import match_image
from psvs.match.rows import RowCheck, row_shift, shift_counts
from psvs.simulate.builtin import builtin_scene
from psvs.simulate.render import render
from psvs.simulate.sensor import Sensor, expose
from tests.support.cli import run


def outline(rng, n=400):
    """A random closed outline (an ellipse with a wobble, 25-60 px radii) as distinct integer pixels (u, v),
    centred at (450, 200)."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    a, b = rng.uniform(25, 60, 2)
    wob = 1 + 0.1 * np.sin(rng.integers(2, 5) * t + rng.uniform(0, 6))
    pts = np.rint(np.column_stack([450 + a * wob * np.cos(t), 200 + b * wob * np.sin(t)])).astype(int)
    return np.unique(pts, axis=0).T


@pytest.mark.parametrize("seed", range(8))
def test_a_drawn_outline_is_found_at_its_planted_row_shift(seed):
    """The twin of a random outline at disparity d (100-300 px, drifting up to 0.05 px a row: a slanted
    surface) and planted s rows down: every pixel is found at shift s (the disparity linear in v), and
    fewer at any shift 2 or more rows away; read as "fit" at s = 0, "off" at |s| >= 2, with shift s."""
    rng = np.random.default_rng(seed)
    u, v = outline(rng)
    d, slope, planted = rng.uniform(100, 300), rng.uniform(-0.05, 0.05), int(rng.integers(-5, 6))
    ru = np.rint(u - d - slope * (v - v.mean())).astype(int)
    counts = shift_counts((u, v), (ru, v + planted), d)
    assert counts[6 + planted] == len(u)
    others = np.abs(np.arange(-6, 7) - planted) >= 2
    assert counts[others].max() < 0.8 * len(u), counts
    rs = row_shift(counts, 10)
    if abs(planted) >= 2:
        assert (rs.verdict, rs.shift) == ("off", planted), rs
    elif planted == 0:
        assert (rs.verdict, rs.shift) == ("fit", 0), rs


def test_a_straight_steep_edge_cannot_tell_and_says_so():
    """A straight line at 60 deg to the row, its twin 3 rows down: every shift finds every pixel but those its
    shift takes past the line's ends (the aperture problem): 120 - |s - 3|, "flat", neither fit nor off."""
    v = np.arange(100, 220)
    u = np.rint(400 + 0.5 * (v - 100)).astype(int)
    counts = shift_counts((u, v), (u - 150, v + 3), 150.0)
    assert np.array_equal(counts, len(v) - np.abs(np.arange(-6, 7) - 3)), counts
    assert row_shift(counts, 10).verdict == "flat"


def test_the_decision_needs_a_margin_and_the_check_its_fits():
    """Hand-made counts: 0-1 px against 2+ px off the rows decide only by max(min_rows, 20 % of the
    winner's count); an image is refused when a pair is off and none fits."""
    flat = np.full(13, 100)
    assert row_shift(flat, 10).verdict == "flat"
    for best, verdict in ((126, "off"), (125, "off"), (124, "flat")):     # margins 26, 25, 24 vs 25.2, 25, 24.8
        counts = flat.copy()
        counts[6 + 4] = best
        assert row_shift(counts, 10).verdict == verdict, best
    off = row_shift(np.where(np.arange(13) == 6 + 4, 200, 100), 10)
    assert (off.verdict, off.shift, off.at_shift, off.at_zero) == ("off", 4, 200, 100)
    one = row_shift(np.where(np.arange(13) == 6 + 1, 200, 100), 10)
    assert (one.verdict, one.shift) == ("fit", 1)                 # 1 row: the edge map's rounding, on the rows
    check = RowCheck()
    assert not check.refuses
    check.off.append((150.0, off))
    assert check.refuses and "+4 rows off" in check.describe() and "200 px shifted, 100 px on its rows" \
        in check.describe(), check.describe()
    check.fits = 1
    assert not check.refuses


@pytest.fixture(scope="module")
def fig5b_views():
    rig = default_rig()
    r = render(builtin_scene("fig5b"), rig, seed=3)
    return rig, r


def _moved(rig, r, rows):
    """Fig. 5b's complex image with its right view moved ``rows`` rows down (the sensor's noise on top)."""
    s = rig.mirrors.split_ratio
    return expose((1 - s) * r.left + s * np.roll(r.right, rows, axis=0), Sensor(), seed=abs(rows))


@pytest.mark.parametrize("rows", [0, 1])
def test_fig5b_on_its_rows_is_answered(fig5b_views, rows):
    """The render as it is, and with the right view 1 row off (the edge map's rounding): answered, at Fig. 5b's
    disparities (148-155 px)."""
    rig, r = fig5b_views
    res = match_image(_moved(rig, r, rows), rig)
    assert res.pairs and not res.rows.refuses and res.rows.fits >= 1, res.rows
    assert all(140 <= p.shape_disparity_px <= 160 for p in res.pairs), [p.shape_disparity_px for p in res.pairs]


@pytest.mark.parametrize("rows", [-4, 3, 5])
def test_fig5b_with_a_view_moved_rows_is_refused(fig5b_views, capsys, tmp_path, rows):
    """The right view moved 3-5 rows (up or down): no pair, the strongest pair refused says how far off, and
    the CLI exits 1 with that one line, writing nothing."""
    rig, r = fig5b_views
    image = _moved(rig, r, rows)
    res = match_image(image, rig)
    assert not res.pairs and res.rows.refuses
    assert max(res.rows.off, key=lambda o: o[1].at_shift)[1].shift == rows, res.rows.off
    path = tmp_path / "moved.png"
    write_png(path, image)
    code, out, err = run(capsys, "match", str(path), "--rig", "default", "--auto", "-o", str(tmp_path / "m.json"))
    assert code == 1 and out == "" and err.count("\n") == 1, (code, out, err)
    assert f"{rows:+d} rows off the rig's rows" in err and "psvs check" in err, err
    assert not (tmp_path / "m.json").exists()
    with pytest.raises(MeasurementError, match="on the rig's rows"):
        from psvs.cli.match_cmd import refuse_unanswered
        refuse_unanswered(res, seeded=False)


@pytest.fixture(scope="module")
def knocked_fig5a():
    """Fig. 5a through the misaligned build after the knock of issue 43 (M3 0.06 deg, M4 0.03 and 0.05 deg)."""
    return render(builtin_scene("fig5a"), load_rig("misaligned_knocked"), seed=5).image


@pytest.mark.parametrize("seed_px", [None, (466, 329)], ids=["auto", "seeded"])
def test_a_knocked_build_is_refused_through_its_old_calibration(knocked_fig5a, seed_px):
    """Issue 43's knock: through the build's calibration before the knock, the twins line up 2 rows off
    (automatic and from a seed on the nearer object's edge): no pair. Through the rig as it now is (its
    truth), they sit on its rows and pair."""
    old = match_image(knocked_fig5a, load_rig("misaligned"), seed_px=seed_px)
    assert not old.pairs and old.rows.refuses, old.rows
    assert max(old.rows.off, key=lambda o: o[1].at_shift)[1].shift == 2, old.rows.off
    now = match_image(knocked_fig5a, load_rig("misaligned_knocked"), seed_px=seed_px)
    assert now.pairs and now.rows.fits >= 1 and not now.rows.off, now.rows


def test_a_frame_of_another_build_is_refused_by_its_own_twins(capsys, tmp_path):
    """An adversarial trial's case: the textured scene through the misaligned build, matched through the ideal
    rig. Where the 7 px field of row offsets crosses zero, some pairs fit their rows, so the pairs' own check
    let three through, two of them 170 and 320 mm off. The image's self-check reads it drifted: exit 1, one
    line naming the field, nothing written. Through its own rig the same frame is answered."""
    path, out = tmp_path / "tex.png", tmp_path / "m.json"
    assert run(capsys, "simulate", "textured", "--rig", "misaligned", "--supersample", "1", "-o", str(path))[0] == 0
    code, stdout, err = run(capsys, "match", str(path), "--rig", "default", "--auto", "-o", str(out))
    assert code == 1 and stdout == "" and err.count("\n") == 1, (code, stdout, err)
    assert err.startswith("psvs match: cannot measure: the rig does not fit this image: the twins stand off their "
                          "rows: ") and "psvs check" in err and not out.exists(), err
    code, stdout, err = run(capsys, "match", str(path), "--rig", "misaligned", "--auto", "-o", str(out))
    assert code == 0 and out.exists() and "edge 0:" in stdout, (code, stdout, err)


def test_live_tracking_refuses_a_seed_off_the_rigs_rows(knocked_fig5a, capsys, tmp_path):
    """An adversarial trial (2026-12-06): `match --seed` refused a frame through the wrong rig, `live --seed` on
    the same frame answered 665.5 mm (651.1 through the right rig), exit 0. The tracker's first match now asks
    the rows as match --seed does: through the old calibration the frame is refused with the same words, and
    `psvs live` exits 1 saying so; through the rig as it is, the tracked depth is match --seed's."""
    from psvs.live.tracker import EdgeTracker
    seed = (466, 329)
    step = EdgeTracker(load_rig("misaligned"), seed).step(knocked_fig5a)
    assert not step.ok and step.message.startswith("the seed's edge has no twin on the rig's rows: ")
    assert "+2 rows off the rig's rows" in step.message, step.message
    step = EdgeTracker(load_rig("misaligned_knocked"), seed).step(knocked_fig5a)
    pair = match_image(knocked_fig5a, load_rig("misaligned_knocked"), seed_px=seed).pairs[0]
    assert step.ok and step.depth_mm == pytest.approx(float(np.nanmedian(pair.points_mm[:, 2])), abs=1e-6)
    folder = tmp_path / "seq"
    folder.mkdir()
    write_png(folder / "f000.png", knocked_fig5a)
    code, out, err = run(capsys, "live", "--video", str(folder), "--rig", "misaligned", "--seed", "466,329",
                         "-o", str(tmp_path / "log.csv"))
    assert code == 1 and "on the rig's rows" in err and "+2 rows off" in err and err.count("\n") == 1, (out, err)
