"""Triangulation: correspondences projected by an independent model through the default rig
(3 mm plate, 400-1200 mm, whole field) are recovered by each triangulation model."""
import numpy as np
import pytest

from psvs.measure.triangulate import fit_refraction_terms, triangulate
from psvs.optics.project import in_image, project_points
from psvs.optics.rig import MirrorExtent
from tests.support.geometry import whole_field_points


@pytest.fixture(scope="module")
def reference_matches(reference):
    """Planted points over the whole field and their pixels from the independent reference model, kept
    where both pixels lie on the sensor (the plate moves the left view's outermost columns of the grid up
    to 2 px off it: no camera sees those, and triangulation refuses them, tested below)."""
    from psvs import default_rig
    rig = default_rig()
    def make(depths, n_side):
        pts = whole_field_points(rig, n_side=n_side, depths=depths)
        left = np.array([reference.project_left(p) for p in pts])
        right = np.array([reference.project_right(p) for p in pts])
        seen = in_image(left, rig) & in_image(right, rig)
        return pts[seen], left[seen], right[seen]
    test = make(np.linspace(400, 1200, 9), 9)
    train = make(np.linspace(425, 1175, 6), 7)  # other points, for fitting l and m
    return test, train


def test_exact_mode_recovers_points(rig, reference_matches):
    (pts, left, right), _ = reference_matches
    res = triangulate(left, right, rig, model="exact")
    assert res.valid.all()
    assert np.abs(res.points_mm - pts).max() < 1e-6


def test_refraction_model_with_fitted_terms(rig, reference_matches):
    (pts, left, right), (tp, tl, tr) = reference_matches
    l_mm, m_mm = fit_refraction_terms(tl, tr, tp, rig)
    res = triangulate(left, right, rig.replace(refraction_l_mm=l_mm, refraction_m_mm=m_mm), model="refraction")
    err = np.linalg.norm(res.points_mm - pts, axis=1)
    assert err.mean() < 0.25
    # fitted terms stay close to the first-order derivation (l 1.81 mm, m 1.01 mm)
    assert 1.7 < l_mm < 2.2 and 0.95 < m_mm < 1.1


def test_refraction_model_with_derived_terms(rig, reference_matches):
    """First-order l, m from d, n, omega_1 (Taylor about the axis): ~0.3-0.4 mm mean over a field-edge-heavy
    grid, because the plate shift is convex in x_l (docs/optics.md); fitting l, m halves that."""
    (pts, left, right), _ = reference_matches
    err = np.linalg.norm(triangulate(left, right, rig).points_mm - pts, axis=1)
    assert err.mean() < 0.5


def test_paper_model_bias_is_about_one_percent(rig, reference_matches):
    """Eq. (12) ignores the plate. The left ray's offset m ~ 1.007 mm widens the baseline to b + m, so
    z - z_v is underestimated by m / (b + m) ~ 1.0 %, i.e. Z by ~1.0-1.1 % (the -b/2 term adds a bit)
    plus the x_l-dependent part l. Documented size: mean relative Z error between -1.4 % and -0.9 %."""
    (pts, left, right), _ = reference_matches
    res = triangulate(left, right, rig, model="paper")
    rel = (res.points_mm[:, 2] - pts[:, 2]) / pts[:, 2]
    assert -0.014 < rel.mean() < -0.009
    assert np.all(rel < 0)


def test_paper_and_refraction_models_are_exact_without_plate(rig):
    flat = rig.replace(plate_thickness_mm=0.0)
    pts = whole_field_points(flat, n_side=5)
    left, _ = project_points(pts, flat, "left")
    right, _ = project_points(pts, flat, "right")
    for model in ("paper", "refraction", "exact"):
        np.testing.assert_allclose(triangulate(left, right, flat, model=model).points_mm, pts, atol=1e-8)


def test_refraction_overrides_are_used(rig):
    left, right = [[400.0, 239.5]], [[300.0, 239.5]]
    base = triangulate(left, right, rig.replace(refraction_l_mm=0.0, refraction_m_mm=0.0)).points_mm[0, 2]
    paper = triangulate(left, right, rig, model="paper").points_mm[0, 2]
    moved = triangulate(left, right, rig.replace(refraction_l_mm=0.0, refraction_m_mm=1.0)).points_mm[0, 2]
    assert base == pytest.approx(paper, abs=1e-12)
    assert moved - base == pytest.approx(11.3 * 1.0 / 1.0, abs=1e-9)  # f m / D with D = 1 mm


@pytest.mark.parametrize("model", ["paper", "refraction", "exact"])
def test_invalid_rows_become_nan(rig, model):
    left = [[400.0, 239.5], [300.0, 239.5], [np.nan, 239.5], [420.0, 239.5]]
    right = [[300.0, 239.5], [300.0, 239.5], [300.0, 239.5], [500.0, 239.5]]
    res = triangulate(left, right, rig, model=model)
    assert res.valid.tolist() == [True, False, False, False]
    assert np.isnan(res.points_mm[1:]).all() and np.isfinite(res.points_mm[0]).all()


def test_exact_mode_flags_vignetted_rays(rig):
    tiny = rig.with_extents({"m3": MirrorExtent((-5.0, 5.0), (-5.0, 5.0))})
    res = triangulate([[319.5, 239.5], [600.0, 239.5]], [[219.5, 239.5], [500.0, 239.5]], tiny, model="exact")
    assert res.valid.tolist() == [True, False]


def test_argument_errors(rig):
    with pytest.raises(ValueError, match="model must be one of paper, refraction, exact"):
        triangulate([[1, 2]], [[0, 2]], rig, model="magic")
    with pytest.raises(ValueError, match="same number of rows, got 2 and 1"):
        triangulate([[1, 2], [3, 4]], [[0, 2]], rig)
    with pytest.raises(ValueError, match=r"right_px must have shape \(N, 2\)"):
        triangulate([[1, 2]], [[0, 2, 3]], rig)
    with pytest.raises(ValueError, match="needs at least 2 pairs with a positive disparity"):
        fit_refraction_terms([[1, 2]], [[0, 2]], [[0, 0, 500]], rig)


def test_example_matches_recover_their_truth(clear_rig):
    """examples/matches.csv (projected through examples/rigs/clear.toml) against examples/matches_truth.csv."""
    from psvs.io.points import read_matches_csv
    from tests.support.geometry import EXAMPLES
    left, right = read_matches_csv(EXAMPLES / "matches.csv")
    truth = np.loadtxt(EXAMPLES / "matches_truth.csv", delimiter=",", skiprows=1)
    res = triangulate(left, right, clear_rig, model="exact")
    assert res.valid.all()
    np.testing.assert_allclose(res.points_mm, truth, atol=1e-6)


@pytest.fixture(scope="module")
def planted_pairs():
    """Three points through the clear rig (finite mirrors) and their exact pixels in both views."""
    from psvs.io.params import load_rig
    rig = load_rig("clear")
    pts = np.array([[0.0, 0.0, 500.0], [40.0, -30.0, 800.0], [-60.0, 20.0, 1100.0]])
    left, okl = project_points(pts, rig, "left")
    right, okr = project_points(pts, rig, "right")
    assert (okl & okr & in_image(left, rig) & in_image(right, rig)).all()
    return rig, pts, left, right


@pytest.mark.parametrize("model", ["paper", "refraction", "exact"])
def test_pixels_off_the_sensor_are_refused(planted_pairs, model):
    """A pixel outside -0.5..W-0.5 x -0.5..H-0.5 (in either view) was seen by no pixel of the camera: NaN,
    valid = 0, for every model; the sensor's outer edges themselves still count."""
    rig, pts, left, right = planted_pairs
    good = triangulate(left, right, rig, model=model)
    assert good.valid.all()
    tol = 1e-6 if model == "exact" else 0.02 * pts[:, 2].max()
    assert np.abs(good.points_mm - pts).max() < tol
    w, h = rig.camera.image_size_px
    moves = [(0, 0, -0.51), (0, 0, w - 0.49), (0, 1, -0.51), (0, 1, h - 0.49),
             (1, 0, -0.51), (1, 0, w - 0.49), (1, 1, -0.51), (1, 1, h - 0.49)]
    for view, axis, value in moves:
        pair = [left.copy(), right.copy()]
        pair[view][0, axis] = value
        res = triangulate(*pair, rig, model=model)
        assert res.valid.tolist() == [False, True, True], (view, axis, value)
        assert np.isnan(res.points_mm[0]).all() and np.isfinite(res.points_mm[1:]).all()
    edge = triangulate([[w - 0.5, 239.5]], [[w - 100.5, 239.5]], rig, model=model)
    assert edge.valid.all()


@pytest.mark.parametrize("model", ["paper", "refraction", "exact"])
def test_rays_that_do_not_meet_in_front_of_the_rig_are_refused(planted_pairs, model):
    """Left and right swapped (the point would be behind the rig: the rays diverge) and negative
    disparities: NaN, valid = 0."""
    rig, _, left, right = planted_pairs
    swapped = triangulate(right, left, rig, model=model)
    assert not swapped.valid.any() and np.isnan(swapped.points_mm).all()
    back = right.copy()
    back[:, 0] = left[:, 0] + 7.0                     # x_l - x_r = -7 px
    res = triangulate(left, back, rig, model=model)
    assert not res.valid.any() and np.isnan(res.points_mm).all()


@pytest.mark.parametrize("model", ["paper", "refraction", "exact"])
def test_points_inside_the_mirror_box_are_refused(model):
    """With a 4 mm lens a disparity of 500 px on the sensor puts the point at Z ~ 30 mm: inside the mirror
    box (its far mirror M3 at Z = 44 mm), where no scene point is seen through the mirrors; 400 px puts it
    at ~50 mm, beyond the box."""
    from psvs.optics.mirrors import front_z_mm
    rig = default_rig_with(focal_length_mm=4.0)
    assert front_z_mm(rig) == pytest.approx(44.0)
    res = triangulate([[600.0, 239.5], [500.0, 239.5]], [[100.0, 239.5], [100.0, 239.5]], rig, model=model)
    assert res.valid.tolist() == [False, True]
    assert 44.0 < res.points_mm[1, 2] < 60.0


def default_rig_with(**changes):
    from psvs import default_rig
    return default_rig().replace(**changes)


def test_the_front_of_the_rig():
    """Unbounded mirrors: M3's anchor at Z = c2 (44 mm); finite ones: their far corners (M3 of the clear rig
    reaches 44 + 53.72 cos 45 deg = 81.99 mm)."""
    from psvs.io.params import load_rig
    from psvs.optics.mirrors import front_z_mm
    assert front_z_mm(default_rig_with()) == pytest.approx(44.0)
    assert front_z_mm(load_rig("clear")) == pytest.approx(44.0 + 53.72226252195192 * np.sqrt(0.5))


def test_the_docs_figures_are_what_the_models_give(rig, reference_matches):
    """docs/optics.md's table of the models' errors and the README's rows quoting it are recomputed here
    to their printed digits (they had drifted from the code: 729 points, 9.96 mm, 0.41 mm)."""
    import re
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    (pts, left, right), (tp, tl, tr) = reference_matches
    l_mm, m_mm = fit_refraction_terms(tl, tr, tp, rig)
    rigs = {"plate ignored": (rig, "paper"), "l, m derived": (rig, "refraction"),
            "l, m fitted on other points": (rig.replace(refraction_l_mm=l_mm, refraction_m_mm=m_mm), "refraction")}
    optics = (root / "docs" / "optics.md").read_text()
    assert f"Measured on {len(pts)} correspondences" in optics
    assert f"l = {l_mm:.2f} mm, m = {m_mm:.2f} mm" in optics
    got = {}
    for row, (r, model) in rigs.items():
        p = triangulate(left, right, r, model=model).points_mm
        err = np.linalg.norm(p - pts, axis=1)
        bias = 100 * np.mean((p[:, 2] - pts[:, 2]) / pts[:, 2])
        got[row] = (err.mean(), bias)
        line = next(ln for ln in optics.splitlines() if ln.startswith("| eqs.") and f", {row} |" in ln)
        mean, top, printed_bias = re.findall(r"\| (−?[\d.]+) (?:mm|%)", line)
        assert float(mean) == pytest.approx(err.mean(), abs=0.005), line
        assert float(top) == pytest.approx(err.max(), abs=0.05 if err.max() > 1 else 0.005), line
        assert float(printed_bias.replace("−", "-")) == pytest.approx(bias, abs=0.005), line
    exact = np.linalg.norm(triangulate(left, right, rig, model="exact").points_mm - pts, axis=1)
    assert "| exact ray tracing | < 1e-10 mm | < 1e-9 mm | 0 |" in optics
    assert exact.mean() < 1e-10 and exact.max() < 1e-9
    readme = (root / "README.md").read_text()
    assert "| depth, exact optics | — | < 1e-10 mm (rounding) |" in readme
    assert f"fitted: l = {l_mm:.2f}, m = {m_mm:.2f} mm" in readme
    paper_err, paper_bias = got["plate ignored"]
    assert f"−{-paper_bias:.2f} % depth bias on a 3 mm plate (mean error {paper_err:.2f} mm" in readme
    assert (f"mean error {got['l, m derived'][0]:.2f} mm (derived l, m), "
            f"{got['l, m fitted on other points'][0]:.2f} mm (fitted)") in readme


@pytest.mark.parametrize("sigma_px", [0.1, 0.5])
def test_depth_sigma_is_the_paper_depth_moved_by_the_noise(sigma_px):
    """depth_sigma_mm against eq. (12) written out: for the paper's ideal cameras Z = f b / d - b / 2 (d the
    disparity on the sensor, mm), so a match sigma px off moves Z to f b / (d -+ sigma pitch) - b / 2; the
    larger move is the near side's. A disparity within sigma: the move passes through infinity (inf)."""
    from psvs import default_rig
    from psvs.measure.triangulate import depth_sigma_mm
    rig = default_rig().replace(plate_thickness_mm=0.0)
    f, b, pitch = rig.camera.focal_length_mm, rig.mirrors.baseline_mm, rig.camera.pixel_pitch_mm[0]
    d_px = np.array([150.0, 60.0, 12.0, 2.0, 0.5 * sigma_px + 0.01, 0.02])
    left = np.column_stack([319.5 + d_px / 2, np.full(len(d_px), 239.5)])
    right = np.column_stack([319.5 - d_px / 2, np.full(len(d_px), 239.5)])
    got = depth_sigma_mm(left, right, rig, "paper", sigma_px)
    z = f * b / (d_px * pitch) - b / 2
    want = f * b / ((d_px - sigma_px) * pitch) - b / 2 - z
    far = d_px > sigma_px
    np.testing.assert_allclose(got[far], want[far], rtol=1e-9)
    assert np.isinf(got[~far]).all()
    # pinned (sigma below Z) exactly where the disparity stands above twice the noise
    assert ((got < z) == (d_px > 2 * sigma_px)).all()


def test_depth_sigma_refuses_a_noise_that_is_no_number():
    from psvs import default_rig
    from psvs.measure.triangulate import depth_sigma_mm
    for bad in (0.0, -0.1, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="the match noise must be a positive number of px"):
            depth_sigma_mm([[400.0, 240.0]], [[300.0, 240.0]], default_rig(), "paper", bad)
    # a noise no match on a camera's pixels has: 1e-9 px called a 0.01 px disparity a point 11 km away, pinned
    for tiny in (1e-9, 0.009):
        with pytest.raises(ValueError, match="below what any match on a camera's pixels reaches"):
            depth_sigma_mm([[320.01, 239.5]], [[320.0, 239.5]], default_rig(), "paper", tiny)
    assert np.isfinite(depth_sigma_mm([[400.0, 240.0]], [[300.0, 240.0]], default_rig(), "paper", 0.01)).all()


def test_triangulate_leaves_a_disparity_within_the_noise_unpinned(tmp_path, capsys):
    """Issue 41's trial: a 0.01 px disparity came out as a valid point 11 km away. Its depth is not pinned by
    matches of 0.1 px noise: invalid, said in one line; the pinned rows keep their points and read back (csv)
    with their sigma."""
    import csv

    from psvs.cli.main import main
    src = tmp_path / "m.csv"
    src.write_text("u_l,v_l,u_r,v_r\n400.0,240,399.99,240\n400,240,300,240\n400,240,399.5,240\n")
    out = tmp_path / "p.csv"
    assert main(["triangulate", "--rig", "clear", str(src), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert err.startswith("1 pair(s) have a disparity within twice the match noise (0.1 px): their depth is not "
                          "pinned (row 2: Z 11428283 mm, +-inf mm), marked invalid"), err
    with out.open() as f:
        rows = list(csv.DictReader(f))
    assert [r["valid"] for r in rows] == ["0", "1", "1"] and rows[0]["Z_mm"] == "nan"
    z, s = float(rows[1]["Z_mm"]), float(rows[1]["Z_sigma_mm"])
    assert 1000 < z < 1200 and 0.5 < s < 2.0
    # with matches to the pixel (0.5 px) the 0.5 px disparity is not pinned either
    assert main(["triangulate", "--rig", "clear", str(src), "--match-sigma-px", "0.5", "-o", str(out)]) == 0
    with out.open() as f:
        assert [r["valid"] for r in csv.DictReader(f)] == ["0", "1", "0"]


def test_depth_sigma_near_the_sensor_edge_moves_the_other_pixel():
    """A right pixel 0.05 px inside the sensor's edge: moving it by the noise leaves the sensor, so the same
    change of disparity is made by moving the left pixel the other way. The depth's move is then what it is
    a pixel further in (within 2 %), not inf (the review found every such pair marked unpinned)."""
    from psvs import default_rig
    from psvs.measure.triangulate import depth_sigma_mm
    rig = default_rig()
    ul = np.linspace(100.0, 630.0, 6)           # Z 130-1080 mm
    left = np.column_stack([ul, np.full(6, 239.5)])
    edge = np.column_stack([np.full(6, -0.45), np.full(6, 239.5)])
    assert triangulate(left, edge, rig).valid.all()
    got = depth_sigma_mm(left, edge, rig)
    inside = depth_sigma_mm(left + [1.0, 0.0], edge + [1.0, 0.0], rig)
    assert np.isfinite(got).all()
    np.testing.assert_allclose(got, inside, rtol=0.02)
