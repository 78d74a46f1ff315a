import math
from pathlib import Path

import numpy as np
import pytest

from psvs import default_rig
from psvs.io.params import dumps_rig, load_rig, save_rig
from psvs.optics.rig import MirrorExtent

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "rigs" / "default.toml"


def test_example_file_is_the_default_rig():
    assert load_rig(EXAMPLE) == default_rig()


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_round_trip_with_extents_and_overrides(tmp_path, suffix):
    rig = default_rig().replace(angle_rad=math.radians(40), refraction_l_mm=1.9, refraction_m_mm=1.02,
                                distortion=(-0.2, 0.05, 0.0, 0.0, 0.0))
    rig = rig.with_extents({"m2": MirrorExtent((-12.5, 26.25), (-13.0, 13.0))})
    path = tmp_path / f"rig{suffix}"
    save_rig(rig, path)
    back = load_rig(path)
    assert back.mirrors.angle_rad == pytest.approx(rig.mirrors.angle_rad, abs=1e-15)
    assert back.replace(angle_rad=rig.mirrors.angle_rad) == rig


def write(tmp_path, text):
    p = tmp_path / "rig.toml"
    p.write_text(text)
    return p


BASE = EXAMPLE.read_text()


@pytest.mark.parametrize("edit, message", [
    (lambda t: t.replace("focal_length_mm = 11.3", "focal_length_mm = -11.3"),
     r"camera\.focal_length_mm must be > 0 mm, got -11\.3"),
    (lambda t: t.replace("baseline_mm = 100.0", "baseline_mm = 100.0\nbaseline = 3"),
     r"unknown key mirrors\.baseline "),
    (lambda t: t.replace("refractive_index = 1.52", "refractive_index = 0.5"),
     r"mirrors\.refractive_index must be >= 1"),
    (lambda t: t.replace("plate_thickness_mm = 3.0", ""), r"missing key mirrors\.plate_thickness_mm"),
    (lambda t: t.replace("image_size_px = [640, 480]", "image_size_px = [640]"),
     r"camera\.image_size_px must be a list of two numbers"),
    (lambda t: t.replace("focal_length_mm = 11.3", 'focal_length_mm = "long"'),
     r"camera\.focal_length_mm must be a number, got str"),
    (lambda t: t.replace("angle_deg = 45.0", "angle_deg = 95.0"), r"mirrors\.angle_deg must be in \(0, 90\)"),
    # the user typed degrees: the message answers in degrees, not in radians
    (lambda t: t.replace("angle_deg = 45.0", "angle_deg = 90"),
     r"mirrors\.angle_deg must be in \(0, 90\) degrees, got 90$"),
    (lambda t: t.replace("split_ratio = 0.5", "split_ratio = 1.0"),
     r"mirrors\.split_ratio must be in \(0, 1\) \(at 0 or 1 one view"),
    (lambda t: t.replace("split_ratio = 0.5", "split_ratio = 0"), r"mirrors\.split_ratio must be in \(0, 1\)"),
    (lambda t: t.replace("m2_axis_distance_mm = 44.0", "m2_axis_distance_mm = 20.0"),
     r"m2_axis_distance_mm must be > m1_axis_distance_mm"),
    (lambda t: t + "\n[mirrors.m5]\nalong_mm = [0, 1]\n", r"unknown key mirrors\.m5"),
    (lambda t: t + "\n[mirrors.m1]\nalong_mm = [2, 1]\nheight_mm = [-1, 1]\n",
     r"mirrors\.m1\.along_mm must be \(min, max\)"),
    (lambda t: t + "\n[lens]\nk1 = 0\n", r"unknown table \[lens\]"),
    (lambda t: t.replace("principal_point_px = [319.5, 239.5]", "distortion_k = [0.1]"),
     r"camera\.distortion_k must be a list of two numbers"),
    (lambda t: t.replace("[camera]", "[camera"), r"malformed TOML"),
])
def test_bad_files_name_the_problem(tmp_path, edit, message):
    path = write(tmp_path, edit(BASE))
    with pytest.raises((ValueError, TypeError), match=message) as info:
        load_rig(path)
    assert str(path) in str(info.value)


def test_missing_file():
    with pytest.raises(FileNotFoundError, match="rig file not found: nope.toml"):
        load_rig("nope.toml")


def test_optional_keys_default(tmp_path):
    text = "\n".join(line for line in BASE.splitlines()
                     if not line.startswith(("principal_point_px", "angle_deg", "split_ratio")))
    rig = load_rig(write(tmp_path, text))
    assert rig == default_rig()


def test_dumps_rejects_unknown_format():
    with pytest.raises(ValueError, match="fmt must be 'toml' or 'json'"):
        dumps_rig(default_rig(), "yaml")


def _build_rig():
    from psvs.optics.rig import MirrorError
    rig = default_rig().replace(distortion=(-0.21, 0.07, 1.2e-3, -8e-4, -0.015), principal_point_px=(324.1, 236.8),
                                box_rotation_rad=(1e-3, -2.5e-3, 4e-4))
    return rig.with_errors({"m1": MirrorError((math.radians(0.2), math.radians(-0.15)), 0.3),
                            "m3": MirrorError((math.radians(-0.25), 0.0), -0.8)}).with_extents(
        {"m2": MirrorExtent((-12.5, 26.25), (-13.0, 13.0))})


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_a_build_round_trips(tmp_path, suffix):
    """rig -> file -> rig to 1e-15 rad (degrees in the file), and file -> rig -> file text unchanged."""
    import json
    import tomllib
    rig = _build_rig()
    path = tmp_path / f"rig{suffix}"
    save_rig(rig, path)
    back = load_rig(path)
    for name in ("m1", "m2", "m3", "m4"):
        np.testing.assert_allclose(back.mirrors.error(name).tilt_rad, rig.mirrors.error(name).tilt_rad, atol=1e-15)
        assert back.mirrors.error(name).shift_mm == rig.mirrors.error(name).shift_mm
    np.testing.assert_allclose(back.mirrors.box_rotation_rad, rig.mirrors.box_rotation_rad, atol=1e-15)
    assert back.camera == rig.camera and back.mirrors.m2_extent == rig.mirrors.m2_extent
    text = path.read_text()
    data = json.loads(text) if suffix == ".json" else tomllib.loads(text)
    assert data["camera"]["distortion"] == [-0.21, 0.07, 1.2e-3, -8e-4, -0.015]
    assert data["mirrors"]["m1"]["tilt_deg"] == [0.2, -0.15] and data["mirrors"]["m3"]["shift_mm"] == -0.8
    assert data["mirrors"]["m2"] == {"along_mm": [-12.5, 26.25], "height_mm": [-13.0, 13.0]}
    save_rig(back, path)
    assert path.read_text() == text


def test_old_files_load_as_designed():
    from psvs.optics.rig import MIRROR_NAMES
    for f in sorted((EXAMPLE.parent).glob("*.toml")):
        rig = load_rig(f)
        if "misaligned" in f.name:
            continue
        assert rig.as_designed and all(rig.mirrors.error(n).is_zero for n in MIRROR_NAMES), f


def test_a_lens_of_two_terms_is_written_with_the_current_key(tmp_path):
    """Trial 52: ``design --rig-out`` wrote a lens of k1 and k2 alone as the older ``distortion_k``; every
    written file now says ``distortion`` (five terms), read back to the same lens by an independent reader."""
    import tomllib
    rig = default_rig().replace(distortion=(-0.12, 0.05, 0.0, 0.0, 0.0))
    path = tmp_path / "r.toml"
    save_rig(rig, path)
    camera = tomllib.loads(path.read_text())["camera"]
    assert camera["distortion"] == [-0.12, 0.05, 0.0, 0.0, 0.0] and "distortion_k" not in camera
    assert load_rig(path).camera.distortion == rig.camera.distortion


@pytest.mark.parametrize("edit, message", [
    (lambda t: t + "\n[mirrors.m1]\ntilt_deg = [0.1]\n", r"mirrors\.m1\.tilt_deg must be a list of two numbers"),
    (lambda t: t + "\n[mirrors.m1]\ntilt_deg = [0.1, \"x\"]\n", r"mirrors\.m1\.tilt_deg must hold numbers \(degrees\)"),
    (lambda t: t + "\n[mirrors.m1]\nshift_mm = nan\n", r"mirrors\.m1\.shift_mm must be finite"),
    (lambda t: t + "\n[mirrors.m1]\ntwist_deg = 1\n", r"unknown key mirrors\.m1\.twist_deg"),
    (lambda t: t + "\n[mirrors.m1]\nalong_mm = [-1, 1]\n", r"missing key mirrors\.m1\.height_mm"),
    (lambda t: t.replace("split_ratio = 0.5", "split_ratio = 0.5\nbox_rotation_deg = [1, 2]"),
     r"mirrors\.box_rotation_deg must be a list of three numbers"),
    (lambda t: t.replace("principal_point_px = [319.5, 239.5]",
                         "principal_point_px = [319.5, 239.5]\ndistortion = [0.1, 0, 0]"),
     r"camera\.distortion must be a list of five numbers"),
    (lambda t: t.replace("principal_point_px = [319.5, 239.5]",
                         "principal_point_px = [319.5, 239.5]\ndistortion = [0, 0, 0, 0, 0]\ndistortion_k = [0, 0]"),
     r"camera\.distortion and camera\.distortion_k are both given"),
])
def test_build_keys_are_checked(tmp_path, edit, message):
    with pytest.raises((ValueError, TypeError), match=message):
        load_rig(write(tmp_path, edit(BASE)))


def test_a_json_rig_with_a_key_given_twice_is_refused_as_such(tmp_path):
    """Trial 32: a JSON rig file holding two "mirrors" objects was read as the last one and refused for a
    'missing key' it did have; TOML refuses a key given twice. JSON now does too, naming the key; the same
    file with the key once loads as the rig dumped."""
    text = dumps_rig(default_rig(), "json")
    mirrors = text[text.index('"mirrors"'):]
    twice = text.replace('"mirrors"', '"mirrors": {"baseline_mm": 90.0},\n  "mirrors"', 1)
    assert twice.count('"mirrors"') == 2 and mirrors
    path = tmp_path / "twice.json"
    path.write_text(twice)
    with pytest.raises(ValueError, match=r"twice\.json: malformed JSON: key 'mirrors' is given twice in one object$"):
        load_rig(path)
    path.write_text(text)
    assert load_rig(path) == default_rig()
