import cv2
import numpy as np
import pytest

from psvs.imaging import steps
from psvs.imaging.pipeline import PAPER, load_pipeline, make_pipeline


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


@pytest.mark.parametrize("op", ["sobel", "prewitt", "laplacian", "canny"])
def test_other_detectors_find_the_square(op):
    edges = make_pipeline([{"op": "gaussian", "sigma": 1.0}, {"op": op}]).run(square_image())
    assert edges[25:95, 45:115].sum() > 150 and edges[:20].sum() == 0


def test_otsu_adaptive_thinning_filters():
    img = square_image()
    assert steps.threshold(img, method="otsu").sum() == 60 * 60
    assert steps.threshold(cv2.GaussianBlur(img, (5, 5), 1), method="adaptive").any()
    thin = make_pipeline([{"op": "mean"}, {"op": "bilateral"}, {"op": "threshold"}, {"op": "roberts"},
                          {"op": "thinning"}]).run(img)
    thick = PAPER.run(img)
    assert 0 < thin.sum() < thick.sum()


def test_stages_are_kept():
    edges, stages = PAPER.run(square_image(), keep=True)
    assert [op for op, _ in stages] == ["median", "threshold", "roberts"]
    assert stages[1][1].dtype == bool and np.array_equal(stages[-1][1], edges)


def test_pipeline_file(tmp_path):
    p = tmp_path / "p.toml"
    p.write_text('[[steps]]\nop = "median"\nksize = 5\n[[steps]]\nop = "threshold"\nmethod = "otsu"\n[[steps]]\nop = "sobel"\n')
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
