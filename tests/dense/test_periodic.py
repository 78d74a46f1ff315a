"""A wall whose texture repeats along the rows (a fence, blinds, a tiled facade) with a period inside the searched
disparities: its complex image repeats with the same period whatever the twins' disparity, so its echo in the
range is a multiple of the period, not the twin (psvs.dense.elsewhere.periodic_patches). An adversarial trial
(walls at 800 mm through the default rig, periods 40-90 px) had 9-70 % of the frame trusted, 60-100 % of it 2-27 %
off; now nothing on such a wall is trusted and `psvs disparity` says why (exit 1)."""
import cv2
import numpy as np
import pytest

from psvs.dense import dense_disparity
from psvs.dense.evaluate import superimpose
from psvs.dense.params import FAST
from psvs.dense.trust import echo_trust
from psvs.io.images import write_png
from tests.support.cli import run

H, W = 480, 640
TRUTH_PX = 134.0            # the twins' disparity: a wall at 800 mm through the default rig


def wall(period_px: int | None, seed: int, grime: float = 0.1) -> np.ndarray:
    """The complex image (H, W) of a wall at TRUTH_PX: a random texture repeating every ``period_px`` along the
    rows (None: not repeating), its rows alike but for ``grime`` of 2-D noise that does not repeat."""
    rng = np.random.default_rng(seed)
    width = W + int(TRUTH_PX) + 2
    if period_px is None:
        texture = cv2.GaussianBlur(rng.random((H, width)), (0, 0), 1.2)
    else:
        raw = np.tile(rng.random((1, period_px)), (1, 3))                # blurred around the period's ends
        profile = cv2.GaussianBlur(raw, (0, 0), 1.2)[:, period_px:2 * period_px]
        texture = np.tile(np.tile(profile, (1, width // period_px + 1))[:, :width], (H, 1))
    texture = (texture - texture.min()) / np.ptp(texture)
    texture = (1 - grime) * texture + grime * cv2.GaussianBlur(rng.random((H, width)), (0, 0), 1.2)
    left = 30 + 200 * texture[:, :W]
    right = 30 + 200 * texture[:, int(TRUTH_PX):int(TRUTH_PX) + W]      # right(x) = left(x + d)
    return superimpose(left, right)


@pytest.mark.parametrize("period", [40, 47, 60, 66, 85])
def test_nothing_on_a_repeating_wall_is_trusted(period):
    img = wall(period, seed=period)
    res = dense_disparity(img, 86, 255)
    trust = echo_trust(img, res)
    assert trust.count == 0, (period, trust.count, np.nanmedian(res.disparity_left[trust.trusted_left]))
    assert trust.elsewhere.periodic_any


def test_the_same_wall_without_the_repeat_is_trusted_and_right():
    """The control: the same wall, its texture not repeating, is answered as before (most of it trusted, within
    1 px of the twins' disparity)."""
    img = wall(None, seed=3)
    res = dense_disparity(img, 86, 255)
    trust = echo_trust(img, res)
    assert not trust.elsewhere.periodic_any
    d = res.disparity_left[trust.trusted_left]
    assert trust.count > 0.5 * (W - TRUTH_PX) * H and np.mean(np.abs(d - TRUTH_PX) <= 1) > 0.95


def test_the_command_says_the_texture_repeats(capsys, tmp_path):
    path = tmp_path / "fence.png"
    write_png(path, np.clip(np.rint(wall(47, seed=5)), 0, 255).astype(np.uint8))
    code, out, err = run(capsys, "disparity", str(path), "--min-disparity", "86", "--max-disparity", "255", "-o",
                         str(tmp_path / "d.npy"))
    assert code == 1 and out == "" and err.count("\n") == 1, (code, out, err)
    assert err.startswith("psvs disparity: cannot measure: the image's texture repeats along its rows: "), err
    assert "px to their left and at a multiple of that" in err and not (tmp_path / "d.npy").exists()


def wallpaper(period_px: int, seed: int) -> np.ndarray:
    """The complex image (H, W) of a wall at TRUTH_PX papered with one random motif repeating every
    ``period_px`` along the rows and the columns (its 2-D texture tells every row apart)."""
    rng = np.random.default_rng(seed)
    motif = cv2.GaussianBlur(np.tile(rng.random((period_px, period_px)), (3, 3)), (0, 0), 1.2)
    motif = motif[period_px:2 * period_px, period_px:2 * period_px]          # blurred across its own edges
    width = W + int(TRUTH_PX) + 2
    texture = np.tile(motif, (H // period_px + 1, width // period_px + 1))[:H, :width]
    texture = (texture - texture.min()) / np.ptp(texture)
    return superimpose(30 + 200 * texture[:, :W], 30 + 200 * texture[:, int(TRUTH_PX):int(TRUTH_PX) + W])


@pytest.mark.parametrize("period", [282, 300])
def test_a_wallpaper_repeating_beyond_the_range_is_not_trusted_at_its_mirror(period):
    """An adversarial trial (2026-12-07): a wall papered with a motif repeating every 212 mm at 800 mm through the
    default rig (282 px, beyond the 86-255 px searched) was trusted on a third of the frame, 97 % of it at the
    lag P - d (148 px for 134: 9.4 % short). Its complex image echoes alike at d and P - d, both in the range;
    the cells whose strongest echo lies above the range at P and which echo at two lags adding up to P
    (psvs.dense.elsewhere.mirrored_patches) are now untrusted with every region reaching them. Here, before:
    72-130 thousand px trusted, 16-81 thousand of them wrong; now 0.7-5.4 thousand, the wrong ones in regions
    near the right edge, whose patches cannot see the repeat (docs/dense.md)."""
    img = wallpaper(period, seed=period)
    for params in (None, FAST):
        res = dense_disparity(img, 86, 255) if params is None else dense_disparity(img, 86, 255, params=params)
        trust = echo_trust(img, res)
        d = res.disparity_left[trust.trusted_left]
        assert trust.elsewhere.mirrored_any and trust.count < 0.03 * H * W, (period, trust.count)
        assert np.sum(np.abs(d - TRUTH_PX) > 2) < 0.02 * H * W, (period, np.nanmedian(d))


def test_the_mirror_pairs_are_read_from_the_echoes():
    """mirrored_patches on planted echoes: a patch echoing strongest above the range at P = 40 lags and in it at
    15 and 25 (adding up to P) is mirrored; at 15 and 20, or strongest inside the range, it is not."""
    from psvs.dense.elsewhere import mirrored_patches
    lags = np.arange(1, 60)
    judged, above = (lags >= 10) & (lags <= 30), lags > 30
    z = np.zeros((len(lags), 1, 4))
    z[40 - 1, :, :3] = 9.0                                    # the repeat above the range: patches 0-2
    z[[15 - 1, 25 - 1], 0, 0] = 5.0                           # 15 + 25 = 40
    z[[15 - 1, 20 - 1], 0, 1] = 5.0                           # 15 + 20: no mirror pair
    z[[16 - 1, 25 - 1], 0, 2] = 5.0                           # 16 + 25 = 41: within one lag
    z[[15 - 1, 25 - 1], 0, 3] = 9.5                           # strongest inside the range
    got = mirrored_patches(z, 4.0, judged, above, lags)
    assert got.tolist() == [[True, False, True, False]]
