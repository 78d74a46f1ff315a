"""`psvs match --auto` on the machine-vision rigs (1440 x 1080, disparities 185-515 px, the lens's fall-off
darkening the corners by 25-30 %): every object of a scene is paired with its twin, at its depth.

A white disc seen by the right view alone (45 % of the light) over the backdrop is grey 126 on the axis and
88 in the corner of mv1440_misaligned, under the paper's threshold 92: the matcher undoes the lens's
fall-off first (psvs.optics.illumination.flat_field), as a machine-vision camera's shading correction does."""
import json

import numpy as np
import pytest

from psvs.cli.main import main
from psvs.io.images import write_png
from psvs.io.params import load_rig
from psvs.simulate.render import render
from psvs.simulate.scene import Lighting, Pose, Scene, SceneObject
from psvs.simulate.textures import Uniform

#: four discs at four depths, no disc's twin crossing another disc, both twins of each inside the image:
#: (x, y, z, r) mm; the second one's left view lies toward the top-right corner (u ~ 1300, v ~ 120), where
#: the lens passes 16-18 % less light
DISCS = [(-60.0, -95.0, 520.0, 18.0), (137.0, -136.0, 700.0, 18.0), (20.0, 0.0, 760.0, 30.0),
         (90.0, 190.0, 1000.0, 35.0)]


def _scene():
    objs = tuple(SceneObject("disc", Pose(np.eye(3), np.array([x, y, z])), Uniform(1.0), radius_mm=r)
                 for x, y, z, r in DISCS)
    return Scene(objs, Lighting(ambient=1.0, lamp=0.0, shadows=False), 1500.0, Uniform(0.08))


@pytest.mark.slow
@pytest.mark.parametrize("name", ["mv1440", "mv1440_misaligned"])
def test_auto_pairs_every_object(name, tmp_path, capsys):
    rig = load_rig(name)
    res = render(_scene(), rig, supersample=1, seed=5)
    png, out = tmp_path / "discs.png", tmp_path / "m.json"
    write_png(png, res.image)
    assert main(["match", str(png), "--rig", name, "--auto", "-o", str(out)]) == 0, capsys.readouterr().err
    data = json.loads(out.read_text())
    assert data["unmatched"] == []
    z = sorted(p["median_z_mm"] for p in data["pairs"])
    assert len(z) == len(DISCS), z
    for (_, _, want, _), got in zip(DISCS, z, strict=True):
        assert got == pytest.approx(want, rel=0.005)
    d = [p["median_disparity_px"] for p in data["pairs"]]
    assert max(d) > 255 and min(d) > 150    # beyond 8 bits: the range comes from the rig


def test_the_fall_off_is_undone_before_the_fixed_threshold():
    """A patch of grey 110 as a flat lens would record it: in mv1440_misaligned's corner (RI 0.70-0.78 over
    the patch) the sensor records it as 77-86, under the paper's threshold 92, so the paper's pipeline finds
    no edge there; the flat-fielded image (what match_image, the tracker, the seam sensor and serve pipe)
    gives it back."""
    from psvs.imaging.pipeline import PAPER
    from psvs.optics.illumination import flat_field, illumination_map
    cam = load_rig("mv1440_misaligned").camera
    ri = illumination_map(cam)
    flat = np.full((1080, 1440), 20.0)
    flat[20:120, 20:140] = 110.0                              # the top-left corner
    flat[490:590, 660:780] = 110.0                            # on the axis
    recorded = np.rint(flat * ri).astype(np.uint8)
    assert recorded[20:120, 20:140].max() < 92 and recorded[540, 720] == 110
    raw = PAPER.run(recorded)
    assert not raw[10:130, 10:150].any() and raw[480:600, 650:790].any()
    fixed = flat_field(recorded, cam)
    assert np.abs(fixed.astype(int) - flat.astype(int)).max() <= 1
    edges = PAPER.run(fixed)
    assert edges[10:130, 10:150].sum() == pytest.approx(edges[480:600, 650:790].sum(), rel=0.02)
