"""Matching through a build whose glass vignettes part of a view (adversarial trial, issue 41: a seed in the
left view's unlit part answered 30 pairs at Z 402 mm, exit 0, where the scene stands at 507-1120 mm; what the
image shows there is not the left view, and `triangulate` refused the same pixels)."""
import numpy as np
import pytest

from psvs import default_rig
from psvs.io.images import write_png
from psvs.io.params import save_rig
from psvs.match.correspondence import match_image
from psvs.optics.design import design_mirrors
from psvs.optics.trace import lit_pairs, trace_pixels
from psvs.simulate.builtin import textured
from psvs.simulate.render import render
from tests.support.cli import run


@pytest.fixture(scope="module")
def vignetting():
    """A layout whose left view loses 15 % of its image to M2 (c2 = 36 mm, the glass sized by the design), and
    the built-in textured scene rendered through it."""
    rig = design_mirrors(default_rig().replace(m2_axis_distance_mm=36.0), search=False).rig
    rr = render(textured(), rig, supersample=1, seed=3)
    return rig, np.clip(rr.image, 0, 255).astype(np.uint8), rr


def test_lit_pairs_are_the_pixels_a_view_sees(vignetting):
    from psvs.simulate.builtin import regulated_light
    from psvs.simulate.scene import Scene
    from psvs.simulate.textures import Noise
    rig = vignetting[0]
    lit_wall = render(Scene((), regulated_light(700.0), 700.0, Noise(scale_mm=2.0, seed=4), "wall"), rig,
                      supersample=1, seed=4)
    u = np.arange(0.0, 640.0, 4.0)
    left = np.stack([u, np.full_like(u, 240.0)], 1)
    right = np.stack([np.full_like(u, 320.0), np.full_like(u, 240.0)], 1)
    lit = lit_pairs(left, right, rig)
    dark = lit_wall.left[240, u.astype(int)] <= 0.0            # the renderer's unlit part of the left view
    assert dark.any() and (~dark).any() and np.array_equal(lit, ~dark)
    assert lit_pairs(left, right, default_rig()).all()       # no sizes (the paper's planes): nothing blocked


def test_no_pair_is_made_of_a_views_unlit_part(vignetting):
    rig, image, _ = vignetting
    res = match_image(image, rig)
    assert res.pairs
    for pair in res.pairs:
        assert trace_pixels(pair.left_px, rig, "left").valid.all()
        assert trace_pixels(pair.right_px, rig, "right").valid.all()


#: Seeds on edges of the image where the glass blocks the left view (what shows there is the right view alone):
#: without the lit-rows check, each paired a "twin" (Z 404, 506, 404, 741 mm; the scene stands at 507-1120 mm)
DARK_SEEDS = ((623, 265), (626, 144), (619, 274), (566, 90))


@pytest.mark.parametrize("seed", DARK_SEEDS)
def test_a_seed_where_the_glass_blocks_the_left_view_pairs_nothing(vignetting, seed):
    rig, image, _ = vignetting
    assert not trace_pixels([seed], rig, "left").valid[0]
    assert match_image(image, rig, seed_px=seed).pairs == []


def test_the_command_refuses_such_a_seed_in_words(capsys, tmp_path, vignetting):
    rig, image, _ = vignetting
    save_rig(rig, tmp_path / "v.toml")
    write_png(tmp_path / "c.png", image)
    u, v = DARK_SEEDS[0]
    code, _, err = run(capsys, "match", str(tmp_path / "c.png"), "--rig", str(tmp_path / "v.toml"),
                       "--seed", f"{u},{v}", "-o", str(tmp_path / "m.json"))
    assert code == 2 and f"the seed ({u}, {v}) lies where the rig's glass blocks the left view" in err
    assert not (tmp_path / "m.json").exists()
