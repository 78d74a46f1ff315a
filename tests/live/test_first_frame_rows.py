"""The first frame of `psvs live --seed` asks what `match --seed` asks: whether anything in it shows that the
rig's rows hold (psvs.match.correspondence.unshown_rows_reason). An adversarial trial (47): a card of a build
read through another rig file (the design's, the build forgotten) was tracked at 767 mm for 650 at 1440 x 1080,
0.3-0.5 % short at 640 x 480, exit 0, where `match` refused the same frame."""
import pytest

from psvs.io.images import write_png
from psvs.io.params import load_rig
from psvs.io.scene_file import load_scene
from psvs.simulate.render import render
from tests.support.cli import run

CARD = ('name = "rect"\n[lighting]\nreference_mm = 800\n[backdrop]\nz_mm = 1400\nalbedo = 0.1\n[[objects]]\n'
        'name = "card"\ntype = "rectangle"\nsize_mm = [70, 50]\nposition_mm = [20, 10, 650]\nalbedo = 0.9\n')


@pytest.fixture(scope="module")
def card_frame(tmp_path_factory):
    """The card at 650 mm (only steep and level straight edges) through the misaligned build."""
    folder = tmp_path_factory.mktemp("card")
    (folder / "rect.toml").write_text(CARD)
    frame = folder / "card.png"
    write_png(frame, render(load_scene(folder / "rect.toml"), load_rig("misaligned"), seed=1).image)
    return frame


def test_a_frame_that_cannot_show_the_rows_is_refused_through_another_rig(capsys, tmp_path, card_frame):
    code, text, err = run(capsys, "live", "--video", str(card_frame), "--rig", "default", "--seed", "385,245",
                          "-o", str(tmp_path / "a.csv"))
    assert code == 1 and len(err.strip().splitlines()) == 1, err
    assert err.startswith("psvs live: cannot measure: the edge was never found: nothing in the image shows that the "
                          "rig's rows hold: its self-check cannot judge"), err
    assert "frame 0: nothing in the image shows" in text
    code, _, err = run(capsys, "match", str(card_frame), "--rig", "default", "--seed", "384,245",   # its edge pixel
                       "-o", str(tmp_path / "a.json"))
    assert code == 1 and "nothing in the image shows that the rig's rows hold" in err      # as match says


def test_the_same_frame_through_its_own_rig_is_tracked(capsys, tmp_path, card_frame):
    code, text, err = run(capsys, "live", "--video", str(card_frame), "--rig", "misaligned", "--seed", "385,245",
                          "-o", str(tmp_path / "b.csv"))
    assert code == 0, err
    z = float(text.split("frame 0: Z ")[1].split(" mm")[0])
    assert z == pytest.approx(650.0, abs=1.0)
