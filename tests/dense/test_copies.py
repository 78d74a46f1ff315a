"""A card of fine stripes before a textured wall: its complex image copies itself every stripe period along the
rows, more closely than any twin's echo can (psvs.dense.echo_test.copied_patches), so its twins cannot be told
from the image. Found at the end of a session (a card of 14 px stripes at 620 mm before a noise wall at 1000
mm, default rig): 17570 card pixels trusted, every one answered at a multiple of the period near the wall's
disparity and more than 2 % off, through the wall's consistent region that the card's answers joined; a
stripe period within the test's short lags, so the periodic-wall rule (psvs.dense.elsewhere) could not see it,
and a periodic profile's standardised peaks stay at 1-2 spreads. Now nothing is trusted in the cells where the
card copies itself (that frame: 0 card pixels trusted), and the wall stays answered. Longer periods (20-60 px)
before a textured wall are not caught yet (docs/right-or-refuse.md, "Not yet")."""
import cv2
import numpy as np
import pytest

from psvs.dense import dense_disparity
from psvs.dense.echo_test import COPY_RHO, copied_patches
from psvs.dense.evaluate import superimpose
from psvs.dense.trust import echo_trust
from psvs.io.images import write_png
from tests.support.cli import run

H, W = 480, 640


def card_before_wall(period_px: float | None, d_card: float, d_wall: float, seed: int, wall_contrast: float = 1.0):
    """(complex image (H, W), left-view truth disparity (H, W), card mask (H, W)): a wall of blurred random
    texture at ``d_wall`` px and, over a 300 x 240 px rectangle of the left view, a card at ``d_card`` px
    carrying vertical square-wave stripes of ``period_px`` (None: the card carries a random texture too)."""
    rng = np.random.default_rng(seed)
    x0, y0 = int(rng.integers(200, 300)), int(rng.integers(80, 160))
    x1, y1 = x0 + 300, y0 + 240
    span = np.arange(-400, W + 400, dtype=float)                  # scene columns, in the left view's px
    wall_tex = 0.5 + wall_contrast * (cv2.GaussianBlur(rng.random((H, span.size)), (0, 0), 1.2) - 0.5)
    if period_px is None:
        card_tex = cv2.GaussianBlur(rng.random((H, span.size)), (0, 0), 1.2)
    else:
        card_tex = np.tile(cv2.GaussianBlur(np.where(np.sin(2 * np.pi * span / period_px) > 0, 0.9, 0.1)[None],
                                            (0, 0), 0.8), (H, 1))
        card_tex += 0.05 * rng.standard_normal(card_tex.shape)
    on_card = np.zeros((H, W), bool)
    on_card[y0:y1, x0:x1] = True
    xs = np.arange(W)
    left = np.where(on_card, card_tex[:, xs + 400], wall_tex[:, xs + 400])
    # the right view at x sees the scene point whose left-view column is x + d: the card where it covers it
    card_seen = np.zeros((H, W), bool)
    card_seen[y0:y1] = ((xs + d_card >= x0) & (xs + d_card < x1))[None]
    right = np.where(card_seen, _sampled(card_tex, xs + d_card + 400), _sampled(wall_tex, xs + d_wall + 400))
    truth = np.where(on_card, d_card, d_wall)
    return superimpose(30 + 200 * left, 30 + 200 * right), truth, on_card


def _sampled(tex: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``tex`` (H, N) at the fractional columns ``cols`` (W,), linearly interpolated: (H, W)."""
    i = np.floor(cols).astype(int)
    f = cols - i
    return (1 - f) * tex[:, i] + f * tex[:, i + 1]


@pytest.mark.parametrize(("period", "d_card", "d_wall", "seed", "contrast"),
                         [(14.0, 170.5, 109.0, 1, 0.6), (17.0, 185.0, 104.0, 3, 1.0), (13.0, 175.0, 112.0, 4, 0.6)])
def test_a_striped_card_before_a_wall_is_not_trusted(period, d_card, d_wall, seed, contrast):
    """Where the card's two views overlap in the complex image it copies itself (no pixel trusted there); where
    one view's card lies over the other's wall it copies itself less closely than the rule asks, and a few
    pixels there stay trusted (the case's figures before the rule: 13873, 69 and 250 card pixels trusted, all
    wrong; now 767, 12 and 250 of 72000: docs/right-or-refuse.md, "Not yet")."""
    img, truth, card = card_before_wall(period, d_card, d_wall, seed, contrast)
    res = dense_disparity(img, 85, 257)
    trust = echo_trust(img, res)
    d, t = res.disparity_left, trust.trusted_left
    assert np.sum(t & card) <= 0.015 * card.sum(), (np.sum(t & card), np.nanmedian(d[t & card]))
    assert trust.test.copied is not None and trust.test.copied.sum() >= 100
    wall = ~card & (np.arange(W)[None] >= d_wall)       # wall pixels whose twin lies in the frame
    right = np.abs(d - truth) <= 0.02 * truth
    assert np.sum(t & wall) > 0.4 * wall.sum() and np.mean(right[t & wall]) > 0.98


def test_the_same_card_without_stripes_is_trusted_and_right():
    """The control: the card carries a random texture, so its patches echo at its twins' disparity and copy
    nothing: most of it trusted, and right."""
    img, truth, card = card_before_wall(None, 170.5, 109.0, 1)
    res = dense_disparity(img, 85, 257)
    trust = echo_trust(img, res)
    t = trust.trusted_left
    assert trust.test.copied is not None and not trust.test.copied.any()
    assert np.sum(t & card) > 0.5 * card.sum()
    # (its trusted outline reaches a little onto the wall behind: 92 % right here, as on Fig. 5b's cards)
    assert np.mean(np.abs(res.disparity_left - truth)[t & card] <= 0.02 * truth[t & card]) > 0.9


def test_a_copy_is_a_correlation_no_twin_can_give():
    """Independently of the images: the twin's correlation in the complex image is at most 1/2 (any split), so
    a patch profile peaking at 0.6 is not a copy, one at COPY_RHO + 0.01 is; NaN lags are ignored."""
    for split in np.linspace(0.05, 0.95, 19):
        assert split * (1 - split) / ((1 - split) ** 2 + split ** 2) <= 0.5 + 1e-12
    rho = np.full((5, 2, 3), 0.1)
    rho[2, 0, 0] = 0.6
    rho[3, 1, 2] = COPY_RHO[2] + 0.01
    rho[:, 0, 1] = np.nan
    assert copied_patches(rho, 2).tolist() == [[False, False, False], [False, False, True]]
    assert copied_patches(np.where(rho > 0.5, COPY_RHO[4] + 0.01, rho), 4).tolist() == [[True, False, False],
                                                                                         [False, False, True]]


def test_a_frame_of_stripes_is_refused_saying_so(capsys, tmp_path):
    img = np.tile(cv2.GaussianBlur(np.where(np.sin(2 * np.pi * np.arange(W) / 13.0) > 0, 220.0, 30.0)[None],
                                   (0, 0), 0.8), (H, 1))
    img = img + np.random.default_rng(4).normal(0, 3, img.shape)
    path = tmp_path / "stripes.png"
    write_png(path, np.clip(np.rint(img), 0, 255).astype(np.uint8))
    code, out, err = run(capsys, "disparity", str(path), "--min-disparity", "85", "--max-disparity", "257", "-o",
                         str(tmp_path / "d.npy"))
    assert code == 1 and out == "" and err.count("\n") == 1, (code, out, err)
    assert err.startswith("psvs disparity: cannot measure: the image's texture repeats along its rows"), err
    assert not (tmp_path / "d.npy").exists()


@pytest.mark.slow
def test_a_striped_card_through_a_build_of_another_format(tmp_path):
    """The same on the 1440 x 1080 mv1440_misaligned build (its rectified grids, tested at half resolution): a
    card of 28 px stripes at 620 mm before a noise wall at 1000 mm had 103285 of its 365872 px trusted, every one
    more than 2 % off; now 826."""
    from psvs.cli.main import main
    from psvs.dense.build import dense_on_rig, rig_cloud, rig_trust
    from psvs.io.images import read_grey
    from psvs.io.params import load_rig
    from tests.support.sweep_scenes import truth_on_left_grid
    rig = load_rig("mv1440_misaligned")
    f_px = rig.camera.focal_length_mm / rig.camera.pixel_pitch_mm[0]
    cycles = 200.0 / (28 * 620 / f_px)                      # stripes across the 200 mm card, 28 px a period
    x = np.arange(3200) * cycles / 3200
    write_png(tmp_path / "stripes.png", np.tile(np.where(x % 1 < 0.5, 230, 25).astype(np.uint8), (400, 1)))
    scene = tmp_path / "card.toml"
    stripes = tmp_path / "stripes.png"
    scene.write_text('name = "stripecard"\n[backdrop]\nz_mm = 1000\ntexture = { type = "noise", scale_mm = 4, '
                     'low = 0.1, high = 0.9 }\n[[objects]]\ntype = "rectangle"\nsize_mm = [200, 150]\n'
                     'position_mm = [-30, 0, 620]\ntexture = { type = "image", file = "%s" }\n' % stripes)
    assert main(["simulate", str(scene), "--rig", "mv1440_misaligned", "-o", str(tmp_path / "card.png"), "--truth",
                 str(tmp_path / "card.npz"), "--supersample", "1"]) == 0
    dense = dense_on_rig(read_grey(tmp_path / "card.png"), rig, 400, 1200)
    trusted = rig_trust(dense).trusted_left
    cloud = rig_cloud(dense, rig)
    truth = truth_on_left_grid(np.load(tmp_path / "card.npz")["depth_left_mm"], dense.rect, cloud.depth_mm.shape)
    card, wall = truth < 800, truth > 900
    right = np.abs(cloud.depth_mm - truth) <= 0.02 * truth
    assert np.sum(trusted & card) <= 0.01 * card.sum(), np.sum(trusted & card)
    assert np.sum(trusted & wall) > 0.3 * wall.sum() and np.mean(right[trusted & wall]) > 0.97
