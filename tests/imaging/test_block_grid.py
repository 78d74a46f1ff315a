"""JPEG's block grid (psvs.imaging.block_grid): its strength against independent constructions, and the dense
answer refused on a frame compressed hard enough for the grid to pull it (an adversarial trial: quality 10,
33 % of the trusted pixels more than 2 % off, at the grid's lag 96 px)."""
import cv2
import numpy as np
import pytest

from psvs import default_rig
from psvs.errors import MeasurementError
from psvs.imaging.block_grid import BLOCK_GRID_LIMIT, block_grid_strength, check_block_grid
from psvs.simulate.builtin import textured
from psvs.simulate.render import render
from tests.support.cli import run


@pytest.fixture(scope="module")
def frame():
    return render(textured(800.0), default_rig(), seed=2, supersample=1).image


def jpeg(image: np.ndarray, quality: int) -> np.ndarray:
    ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, quality])
    assert ok
    return cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)


def test_strength_is_one_without_a_grid_and_grows_as_jpeg_compresses(frame):
    rng = np.random.default_rng(4)
    assert 1.0 <= block_grid_strength(rng.integers(0, 256, (480, 640)).astype(np.uint8)) < 1.03
    assert 1.0 <= block_grid_strength(frame) < 1.1          # a rendered frame: no grid (the strongest of 8 phases)
    strengths = [block_grid_strength(jpeg(frame, q)) for q in (95, 75, 50, 30, 10)]
    assert strengths == sorted(strengths) and strengths[0] < 1.2 and strengths[-1] > 2.0
    # a crop by other than a multiple of 8 px moves the grid, not its strength
    assert block_grid_strength(jpeg(frame, 10)[5:, 3:]) == pytest.approx(strengths[-1], rel=0.02)
    # a planted grid: steps of 10 grey levels at every 8th column of a smooth ramp (other steps 1 level)
    ramp = np.tile(np.arange(64, dtype=float), (32, 1))
    ramp += 9.0 * (np.arange(64) // 8)                  # the step between columns 8k+7 and 8k+8 is 1 + 9
    assert block_grid_strength(ramp) == pytest.approx(10.0)
    assert block_grid_strength(np.zeros((8, 8))) == 1.0 and block_grid_strength(np.full((40, 40), 7.0)) == 1.0


def test_a_hard_compressed_frame_is_refused_and_a_fair_one_answered(frame, capsys, tmp_path):
    hard, fair = jpeg(frame, 20), jpeg(frame, 90)
    with pytest.raises(MeasurementError, match=r"JPEG's 8 px block grid: its grey-level steps across the block "
                                               r"borders are \d\.\d\d times those between"):
        check_block_grid(hard)
    check_block_grid(fair)
    assert block_grid_strength(hard) > BLOCK_GRID_LIMIT > block_grid_strength(fair)
    for name, img, code in (("hard.jpg", hard, 1), ("fair.jpg", fair, 0)):
        cv2.imwrite(str(tmp_path / name), img, [cv2.IMWRITE_JPEG_QUALITY, 100])
        out = tmp_path / f"{name}.npy"
        got, _, err = run(capsys, "disparity", str(tmp_path / name), "--rig", "default", "-o", str(out))
        assert got == code and out.exists() == (code == 0), err
        assert code == 0 or err.startswith("psvs disparity: cannot measure: the image carries JPEG's 8 px block grid")


@pytest.mark.parametrize("period", [24, 32, 40, 48])
def test_stripes_whose_edges_fall_on_one_phase_of_8_are_no_grid(period):
    """Trial 42: a lossless PNG of stripes whose period is a multiple of 8 px was refused as carrying JPEG's
    grid (its edges all on one phase of 8: 4.5-24 by the mean alone). A grid lifts every border: the columns'
    median |step| at that phase is no higher than elsewhere. The same stripes saved at JPEG quality 50 do."""
    x = np.arange(640)
    stripes = np.tile(np.where((x // (period // 2)) % 2 == 0, 200.0, 40.0), (480, 1))
    png = np.clip(stripes + np.random.default_rng(period).normal(0, 3, stripes.shape), 0, 255).astype(np.uint8)
    assert block_grid_strength(png) < 1.1
    assert block_grid_strength(jpeg(png, 50)) > BLOCK_GRID_LIMIT


def test_a_pattern_and_a_tiny_frame_are_no_grid(capsys, tmp_path):
    """The Fig. 9 pattern as a lossless PNG (1.7 by the mean alone: `psvs disparity` refused it as carrying
    JPEG's grid) and, trial 45, a 16 x 16 px crop of it (an axis with fewer than 6 borders a phase is not
    judged: one edge made a phase, 1.62): no grid; the tiny frame is refused for what it is."""
    from psvs.imaging.block_grid import MIN_BORDERS
    from psvs.simulate.builtin import builtin_scene
    fig9 = render(builtin_scene("fig9:distance_mm=600"), default_rig(), seed=1, supersample=1).image
    assert block_grid_strength(fig9) < 1.1 and block_grid_strength(jpeg(fig9, 30)) > BLOCK_GRID_LIMIT
    tiny = fig9[200:216, 300:316]
    assert MIN_BORDERS == 6 and block_grid_strength(tiny) == 1.0
    cv2.imwrite(str(tmp_path / "tiny.png"), tiny)
    code, _, err = run(capsys, "disparity", str(tmp_path / "tiny.png"), "--min-disparity", "2", "--max-disparity",
                       "8", "-o", str(tmp_path / "t.npy"))
    assert code == 1 and "block grid" not in err and "no patch to judge on 16x16 px" in err, err
