import cv2
import numpy as np
import pytest

from psvs import default_rig
from psvs.imaging import steps
from psvs.imaging.pipeline import PAPER, make_pipeline
from psvs.io.pipeline_file import load_pipeline


def square_image(level=200, background=20):
    img = np.full((120, 160), background, np.uint8)
    img[30:90, 50:110] = level
    return img


def test_roberts_on_binary_equals_the_cross_operator():
    """|G1| + |G2| > 0 with the Roberts kernels [[1,0],[0,-1]], [[0,1],[-1,0]] computed by filter2D."""
    rng = np.random.default_rng(0)
    b = rng.random((60, 80)) > 0.6
    f = b.astype(np.float32)
    g1 = cv2.filter2D(f, -1, np.array([[1, 0], [0, -1]], np.float32), anchor=(0, 0), borderType=cv2.BORDER_CONSTANT)
    g2 = cv2.filter2D(f, -1, np.array([[0, 1], [-1, 0]], np.float32), anchor=(0, 0), borderType=cv2.BORDER_CONSTANT)
    ref = (np.abs(g1) + np.abs(g2)) > 0
    np.testing.assert_array_equal(steps.roberts(b)[:-1, :-1], ref[:-1, :-1])
    np.testing.assert_array_equal(steps.roberts(b.astype(np.uint8) * 255, level=0)[:-1, :-1], ref[:-1, :-1])


def test_paper_pipeline_outlines_a_square():
    edges = PAPER.run(square_image())
    # Roberts marks the pixel above-left of each diagonal change: the square's outline, ~2 px wide
    assert edges[29:90, 49:110].sum() == edges.sum()
    assert 230 <= edges.sum() <= 480
    assert not edges[40:80, 60:100].any()


def test_threshold_92_is_strict():
    ramp = np.arange(256, dtype=np.uint8)[None, :].repeat(3, 0)
    b = steps.threshold(ramp)
    assert b[0, 92] == False and b[0, 93] == True  # noqa: E712


def outline_distance_px(shape=(120, 160)) -> np.ndarray:
    """Distance (px) of every pixel centre from the planted square's outline, the lines between pixels
    29|30 and 89|90 (rows), 49|50 and 109|110 (columns)."""
    v, u = np.mgrid[:shape[0], :shape[1]].astype(float)
    inside_u, inside_v = (u >= 49.5) & (u <= 109.5), (v >= 29.5) & (v <= 89.5)
    du = np.minimum(np.abs(u - 49.5), np.abs(u - 109.5))
    dv = np.minimum(np.abs(v - 29.5), np.abs(v - 89.5))
    return np.where(inside_u & inside_v, np.minimum(du, dv),
                    np.where(inside_u, dv, np.where(inside_v, du, np.hypot(du, dv))))


def covered_sides(edges: np.ndarray, within_px: float = 2.0) -> float:
    """Share of the square's four sides (corners 3 px excluded) with an edge pixel within ``within_px``."""
    hits = []
    for r in range(33, 87):
        hits += [edges[r, 47:53].any(), edges[r, 107:113].any()]
    for c in range(53, 107):
        hits += [edges[27:33, c].any(), edges[87:93, c].any()]
    return float(np.mean(hits))


@pytest.mark.parametrize("op", ["sobel", "prewitt", "laplacian", "canny"])
def test_other_detectors_find_the_square(op):
    """Every edge pixel lies on the planted outline (within 2 px: a 3x3 operator after a 1 px blur), and
    the outline is found all round."""
    edges = make_pipeline([{"op": "gaussian", "sigma": 1.0}, {"op": op}]).run(square_image())
    assert edges.any() and outline_distance_px()[edges].max() <= 2.0
    assert covered_sides(edges) == 1.0


def test_otsu_adaptive_thinning_filters():
    img = square_image()
    # Otsu splits the two grey levels: the binary image is the square, exactly
    np.testing.assert_array_equal(steps.threshold(img, method="otsu"), img > 20)
    # adaptive (local mean of a 31 px block - 5): next to the bright square the local mean rises above the
    # dark ground, so a dark band outside the square is cut off; far from it, flat ground passes (> mean - 5)
    ad = steps.threshold(cv2.GaussianBlur(img, (5, 5), 1), method="adaptive")
    assert ad[60, 52:108].all() and not ad[60, 44:48].any() and not ad[24:28, 80].any()
    assert ad[5, 5] and ad[115, 155]
    # thinning turns Sobel's band (2-4 px wide on each side) into a one-pixel line on the outline
    thick = make_pipeline([{"op": "gaussian", "sigma": 1.0}, {"op": "sobel"}]).run(img)
    thin = make_pipeline([{"op": "gaussian", "sigma": 1.0}, {"op": "sobel"}, {"op": "thinning"}]).run(img)
    assert min(thick[r, 44:56].sum() for r in range(35, 85)) >= 2
    assert all(thin[r, 44:56].sum() == 1 and thin[r, 104:116].sum() == 1 for r in range(35, 85))
    assert outline_distance_px()[thin].max() <= 2.0 and covered_sides(thin) == 1.0
    # the paper's own steps with the smoothing filters still outline the square (1 px after thinning)
    smooth = make_pipeline([{"op": "mean"}, {"op": "bilateral"}, {"op": "threshold"}, {"op": "roberts"},
                            {"op": "thinning"}]).run(img)
    assert outline_distance_px()[smooth].max() <= 1.5 and covered_sides(smooth) == 1.0


def test_stages_are_kept():
    edges, stages = PAPER.run(square_image(), keep=True)
    assert [op for op, _ in stages] == ["median", "threshold", "roberts"]
    assert stages[1][1].dtype == bool and np.array_equal(stages[-1][1], edges)


def test_pipeline_file(tmp_path):
    p = tmp_path / "p.toml"
    p.write_text('[[steps]]\nop = "median"\nksize = 5\n'
                 '[[steps]]\nop = "threshold"\nmethod = "otsu"\n'
                 '[[steps]]\nop = "sobel"\n')
    pipe = load_pipeline(p)
    assert [s.op for s in pipe.steps] == ["median", "threshold", "sobel"]


@pytest.mark.parametrize("text, message", [
    ('[[steps]]\nop = "fft"\n', "unknown pipeline step 'fft'"),
    ('[[steps]]\nop = "median"\nsize = 3\n', "step 'median': unknown parameter 'size'"),
    ('[[steps]]\nop = "median"\n', "must end with an edge detector or threshold"),
    ('steps = 3\n', "a pipeline file holds one array of tables"),
    ('[[steps]\n', "malformed TOML"),
])
def test_bad_pipeline_files(tmp_path, text, message):
    p = tmp_path / "p.toml"
    p.write_text(text)
    with pytest.raises(ValueError, match=message):
        load_pipeline(p).run(square_image())


def test_bad_step_values():
    with pytest.raises(ValueError, match="median ksize must be an odd integer"):
        steps.median(square_image(), ksize=4)
    with pytest.raises(ValueError, match="threshold method must be fixed, otsu or adaptive"):
        steps.threshold(square_image(), method="magic")
    with pytest.raises(ValueError, match=r"image must be a grey \(H, W\) uint8 image"):
        PAPER.run(np.zeros((4, 4, 3), np.uint8))
    # trial 32: low above high was taken (OpenCV swaps them without a word)
    for low, high in ((200, 100), (-1, 100), (50, float("inf")), (float("nan"), 100)):
        with pytest.raises(ValueError, match=r"^canny thresholds must satisfy 0 <= low <= high \(finite\), got "):
            steps.canny(square_image(), low=low, high=high)
    assert steps.canny(square_image(), low=100, high=100).any()


@pytest.mark.parametrize("text, message", [
    ('op = "bilateral"\ndiameter = 100000', r"bilateral diameter 100000 px is wider than the image \(40x30 px\)"),
    ('op = "median"\nksize = 99999', r"median ksize 99999 px is wider than the image"),
    ('op = "mean"\nksize = 41', r"mean ksize 41 px is wider than the image \(40x30 px\): a window at most 40 px"),
    ('op = "gaussian"\nsigma = 1e300', r"gaussian window \(6 sigma \+ 1\) 6e\+300 px is wider than the image"),
    ('op = "gaussian"\nsigma = nan', r"gaussian sigma must be a finite number, got nan"),
])
def test_a_window_wider_than_the_image_is_refused_before_it_runs(tmp_path, text, message):
    """Issue 41: a bilateral diameter of 100000 in a pipeline file ran to 17 GB; sigma 1e300 and a 99999 px
    median reached OpenCV and came back as its internal error. A window is at most the image's larger side,
    refused (ValueError: exit 2) before OpenCV is called."""
    p = tmp_path / "p.toml"
    p.write_text(f'[[steps]]\n{text}\n[[steps]]\nop = "sobel"\n')
    with pytest.raises(ValueError, match=message):
        load_pipeline(p).run(np.zeros((30, 40), np.uint8))


def test_a_bilateral_filter_is_timed_before_it_runs(monkeypatch):
    """Its time (pixels x window taps x the measured cost of one) against psvs's work limit: at a limit of
    1 s, a 31 px window on 640x480 (0.28 s estimated) runs and a 101 px one (2.95 s) is refused."""
    import psvs._budget
    monkeypatch.setattr(psvs._budget, "WORK_LIMIT_S", 1.0)
    img = np.zeros((480, 640), np.uint8)
    assert steps.bilateral(img, diameter=31).shape == img.shape
    with pytest.raises(ValueError, match=r"a bilateral filter of diameter 101 px on 640x480 px takes about 2\.9\d s, "
                                         r"more than the 1 s limit; a smaller diameter"):
        steps.bilateral(img, diameter=101)


def test_a_median_window_opencv_cannot_take_is_refused():
    """OpenCV's constant-time 8-bit median fails an assertion on fig5b from 363 px up: psvs refuses windows over
    255 px in one line, and takes 255 (the result checked against a direct median of one pixel's window)."""
    from psvs.simulate.builtin import fig5b
    from psvs.simulate.render import render
    img = render(fig5b(), default_rig(), supersample=1).image
    with pytest.raises(ValueError, match=r"^median ksize must be at most 255 px, got 401$"):
        steps.median(img, 401)
    out = steps.median(img, 255)
    v, u = 240, 320
    window = np.pad(img, 127, mode="reflect")[v:v + 255, u:u + 255]     # OpenCV's border: reflect 101 for 8u
    assert abs(int(out[v, u]) - int(np.median(window))) <= 1


@pytest.mark.parametrize("step, message", [
    # trial 50: OpenCV's assertion came back as "internal error" (exit 1), a NaN went through to a frame of noise
    ({"op": "threshold", "method": "adaptive", "block": 1, "offset": 0},
     r"^threshold block must be an odd integer >= 3, got 1$"),
    ({"op": "threshold", "method": "adaptive", "block": 11, "offset": float("nan")},
     r"^threshold offset must be a finite number, got nan$"),
    ({"op": "threshold", "method": "adaptive", "block": 11, "offset": 1e300},
     r"^threshold offset must be a number >= -255 and <= 255, got 1e\+300$"),
    ({"op": "laplacian", "level": float("nan")}, r"^laplacian level must be a finite number, got nan$"),
    ({"op": "bilateral", "diameter": 5, "sigma_color": float("nan")},
     r"^bilateral sigma_color must be a finite number, got nan$"),
    ({"op": "bilateral", "diameter": 5, "sigma_space": 0.0}, r"^bilateral sigma_space must be a number > 0, got 0.0$"),
    ({"op": "bilateral", "diameter": 5.0}, r"^bilateral diameter must be an integer, got 5.0$"),
    ({"op": "median", "ksize": True}, r"^median ksize must be an odd integer, got True$"),
    ({"op": "sobel", "level": -1}, r"^sobel level must be a number >= 0, got -1$"),
    ({"op": "canny", "low": float("inf")}, r"^canny low must be a finite number, got inf$"),
    ({"op": "threshold", "method": 3}, r"^threshold method must be fixed, otsu or adaptive, got 3$"),
])
def test_a_steps_values_are_checked_when_it_is_made(step, message):
    """Every parameter against psvs.imaging.steps.PARAM_RULES when the step is made (a pipeline file, the web
    page's steps and the library's own pipelines alike): one line naming the step, the parameter and the value."""
    with pytest.raises(ValueError, match=message):
        make_pipeline([step, {"op": "roberts"}])


def test_every_steps_parameter_has_a_rule_and_its_default_keeps_it():
    """No parameter of a step escapes the rules, and every step's defaults pass them."""
    import inspect
    for op, fn in steps.STEPS.items():
        params = inspect.signature(fn).parameters
        for name in list(params)[1:]:
            assert name == "method" or name in steps.PARAM_RULES, (op, name)
            steps.check_param(op, name, params[name].default)
