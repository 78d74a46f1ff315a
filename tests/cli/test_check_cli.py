"""``psvs check`` from the command line: the verdict's exit status, the JSON read back by value, the map."""
import json
import math

import cv2
import numpy as np
import pytest

from psvs.health.check import check_frames
from psvs.health.explain import tilted
from psvs.io.params import load_rig
from psvs.simulate.builtin import regulated_light
from psvs.simulate.render import render
from psvs.simulate.scene import Scene
from psvs.simulate.textures import Noise
from tests.support.cli import run


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    """A frame through the misaligned build as calibrated, and one after M3 leaned 0.08 deg, as PNG files."""
    rig = load_rig("misaligned")
    wall = Scene((), regulated_light(750.0), 750.0, Noise(scale_mm=1.6, seed=5), "wall")
    folder = tmp_path_factory.mktemp("check")
    out = {}
    for name, r in (("ok", rig), ("knocked", tilted(rig, "m3", 0.0, math.radians(0.08)))):
        out[name] = folder / f"{name}.png"
        cv2.imwrite(str(out[name]), render(wall, r, seed=2, supersample=1).image)
    return out


def test_statuses_and_lines(frames, capsys):
    code, out, err = run(capsys, "check", str(frames["ok"]), "--rig", "misaligned")
    assert (code, err) == (0, "") and out.startswith("healthy: the twins stand on their rows")
    # a healthy verdict says what the rows cannot show (issue 41's trial: M3 turned 0.1 deg about the vertical
    # read healthy while depth was 2.6 % far at 700 mm), with the closed form's figure at the range's far end
    said = out.splitlines()[-1]
    assert said.startswith("not checked (the rows cannot show it): a mirror turned about the vertical")
    assert "(a turn of 0.1 deg: 4.5 % at 1200 mm)" in said and "psvs refit --tare" in said
    code, out, err = run(capsys, "check", str(frames["knocked"]), str(frames["knocked"]), "--rig", "misaligned")
    assert code == 3 and err == "" and out.startswith("drifted: the twins stand off their rows")
    assert "of 2 frame(s)" in out and "best explained by" in out and "M3" in out


def test_json_reads_back_as_the_library_s_check(frames, capsys, tmp_path):
    code, out, err = run(capsys, "check", str(frames["knocked"]), "--rig", "misaligned", "--json",
                         "--map", str(tmp_path / "map.png"))
    assert code == 3 and err == ""
    got = json.loads(out)                                      # one object, nothing else on stdout
    rig = load_rig("misaligned")
    lib = check_frames([cv2.imread(str(frames["knocked"]), cv2.IMREAD_GRAYSCALE)], rig)
    assert got["verdict"] == lib.verdict == "drifted"
    for key in ("row_offset_rms_px", "row_offset_max_px", "uncertainty_px", "scatter_px"):
        assert got[key] == pytest.approx(getattr(lib, key), abs=1e-4), key
    assert got["judged_px"] == lib.judged_px > 0 and got["tiles"] == lib.tiles == len(got["tile_offsets_px"])
    np.testing.assert_allclose(np.array(got["tile_centres_px"], float), lib.centre_px, atol=1e-4)
    np.testing.assert_allclose(np.array(got["tile_offsets_px"], float), lib.offset_px, atol=1e-4)
    assert got["explained_by"][0]["mirror"] in ("m1", "m2", "m3", "m4") and len(got["explained_by"]) == 4
    assert got["not_checked"].startswith("not checked (the rows cannot show it)")
    picture = cv2.imread(str(tmp_path / "map.png"))
    assert picture is not None and picture.shape[0] > 400 and picture.shape[1] > 600
    # a positive field (the right twins lower) is drawn red: the map holds far more red than blue pixels
    b, g, r = (picture[..., k].astype(int) for k in range(3))
    assert ((r - b) > 60).sum() > 10 * max(((b - r) > 60).sum(), 1)


def test_nothing_to_judge_exits_1_and_writes_no_map(capsys, tmp_path):
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((480, 640), 90, np.uint8))
    code, out, err = run(capsys, "check", str(blank), "--rig", "misaligned", "--map", str(tmp_path / "m.png"),
                         "--json")
    assert code == 1 and json.loads(out)["verdict"] == "cannot judge"
    assert err.startswith("psvs check: cannot judge: only 0 of") and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "m.png").exists()


def test_a_refusal_is_said_once(capsys, tmp_path):
    """Issue 41's trial: 'cannot judge' was printed on stdout and again on stderr."""
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((480, 640), 90, np.uint8))
    code, out, err = run(capsys, "check", str(blank), "--rig", "misaligned")
    assert code == 1 and out == "" and err.startswith("psvs check: cannot judge: only 0 of")
    assert len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("command", ["check", "disparity"])
def test_a_range_whose_twins_are_beyond_the_image_is_refused_naming_it(capsys, tmp_path, command):
    """An adversarial trial: `check --near-mm 45 --far-mm 60` (twins 1023-1193 px apart in a 640 px image) said
    'only 0 of 0 tiles show a twin'; `disparity` said 'disparity range is empty: min 1023.27 >= max 639.0'. Both
    now refuse the range itself (exit 2, one line, nothing written)."""
    frame = tmp_path / "f.png"
    cv2.imwrite(str(frame), render(Scene((), regulated_light(700.0), 700.0, Noise(scale_mm=1.5, seed=1), "wall"),
                                   load_rig("default"), seed=1, supersample=1).image)
    out_file = tmp_path / "d.npy"
    extra = ["-o", str(out_file)] if command == "disparity" else []
    code, out, err = run(capsys, command, str(frame), "--rig", "default", "--near-mm", "45", "--far-mm", "60", *extra)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
    assert err.startswith(f"psvs {command}: error: at 45-60 mm the twins stand 1023-1193 px apart, beyond the 640 px "
                          "wide image: no point of that range is seen by both views")
    assert not out_file.exists()
