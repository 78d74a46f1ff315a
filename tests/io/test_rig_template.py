"""A rig file written in the comments and layout of the nominal rig's file (what ``psvs calibrate`` does):
read back by value with ``tomllib`` and compared with the rig's own fields, the user's comments still beside
their keys, short arrays on one line, and a file written over itself unchanged."""
import dataclasses
import json
import math
import re
import tomllib
from pathlib import Path

import pytest

from psvs.io.params import dumps_rig, load_rig, rig_template, rig_to_dict, save_rig
from psvs.optics.rig import Calibration, MirrorError
from psvs.rigs import shipped_rig_path

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "rigs"
MY_LENS = "# my lens: the 12 mm one from the drawer, focused at 700 mm"
CALIPERS = "# b, measured with calipers"


def nominal_text() -> str:
    """examples/rigs/default.toml with a comment line of the user's above focal_length_mm and another comment
    after baseline_mm's value."""
    text = (EXAMPLES / "default.toml").read_text()
    text = text.replace("[camera]\n", f"[camera]\n{MY_LENS}\n")
    pad = " " * 18
    return text.replace(f"baseline_mm = 100.0{pad}# b\n", f"baseline_mm = 100.0{pad}{CALIPERS}\n")


def calibrated(start):
    """``start`` as a calibration leaves it: every calibrated value changed, mirror errors, a [calibration]."""
    rig = start.replace(focal_length_mm=11.412736, principal_point_px=(323.8172, 236.5519),
                        distortion=(-0.1987, 0.1043, 0.00118, -0.00091, -0.0287), plate_thickness_mm=2.971,
                        baseline_mm=100.3127, box_rotation_rad=tuple(math.radians(d) for d in (0.118, -0.203, 0.149)),
                        refraction_l_mm=None, refraction_m_mm=None)
    rig = rig.with_errors({name: MirrorError((math.radians(a), math.radians(b)), s) for name, a, b, s in (
        ("m1", 0.181, 0.268, 0.0), ("m2", -0.219, -0.141, 0.0), ("m3", -0.288, 0.112, 0.797),
        ("m4", 0.131, -0.251, 0.0))})
    return dataclasses.replace(rig, calibration=Calibration(0.0262, 0.0251, 0.0273, 16, "16 grid"))


def check_values(raw: dict, rig) -> None:
    """The file's values (read by tomllib) against the rig's fields; angles to the file's 12 digits."""
    c, m = rig.camera, rig.mirrors
    assert raw["camera"]["focal_length_mm"] == c.focal_length_mm
    assert raw["camera"]["principal_point_px"] == list(c.principal_point_px)
    assert raw["camera"]["distortion"] == list(c.distortion)
    assert raw["camera"]["pixel_pitch_mm"] == list(c.pixel_pitch_mm)
    assert raw["camera"]["image_size_px"] == list(c.image_size_px)
    mir = raw["mirrors"]
    for key in ("baseline_mm", "m1_axis_distance_mm", "m2_axis_distance_mm", "plate_thickness_mm", "refractive_index",
                "split_ratio"):
        assert mir[key] == getattr(m, key), key
    assert mir["angle_deg"] == pytest.approx(math.degrees(m.angle_rad), rel=1e-12)
    assert mir["box_rotation_deg"] == pytest.approx([math.degrees(r) for r in m.box_rotation_rad], rel=1e-11)
    for name in ("m1", "m2", "m3", "m4"):
        err = m.error(name)
        assert mir[name]["tilt_deg"] == pytest.approx([math.degrees(t) for t in err.tilt_rad], rel=1e-11), name
        assert mir[name]["shift_mm"] == err.shift_mm
    cal = rig.calibration
    assert raw["calibration"] == {"rms_px": cal.rms_px, "rms_left_px": cal.rms_left_px,
                                  "rms_right_px": cal.rms_right_px, "images": cal.images, "kinds": cal.kinds}


def arrays_on_one_line(text: str) -> bool:
    """Every array of the file (outside comments) opens and closes on its key's line."""
    lines = [line for line in text.splitlines() if "= [" in line and not line.startswith("#")]
    return len(lines) >= 4 and all(re.fullmatch(r"\w+ = \[[^\]\[]*\]\s*(#.*)?", line) for line in lines)


def test_written_over_the_nominal_file(tmp_path):
    nominal = tmp_path / "nominal.toml"
    nominal.write_text(nominal_text())
    rig = calibrated(load_rig(nominal))
    out = tmp_path / "build.toml"
    save_rig(rig, out, template=rig_template(nominal))
    text = out.read_text()
    check_values(tomllib.loads(text), rig)
    assert load_rig(out) == rig
    lines, before = text.splitlines(), nominal_text().splitlines()
    assert lines[:5] == before[:5]                                       # the file's header comments
    k = lines.index(MY_LENS)
    assert lines[k - 1] == "[camera]" and lines[k + 1] == "focal_length_mm = 11.412736"
    (base,) = [line for line in lines if line.startswith("baseline_mm")]
    (base_before,) = [line for line in before if line.startswith("baseline_mm")]
    assert base.startswith("baseline_mm = 100.3127 ") and base.endswith(CALIPERS)
    assert base.index("#") == base_before.index("#")                      # the comment keeps its column
    assert "image_size_px = [640, 480]           # width, height" in lines   # unchanged: as the user wrote it
    assert arrays_on_one_line(text)
    # a file read and written again over itself is unchanged
    again = tmp_path / "again.toml"
    save_rig(load_rig(out), again, template=out.read_text())
    assert again.read_text() == text


def test_keys_the_rig_no_longer_has_go(tmp_path):
    """A nominal file with the old two-term lens, a plate override and an earlier [calibration]: the written
    file has the five-term lens, no override and this calibration's table."""
    text = nominal_text().replace("principal_point_px = [319.5, 239.5]  # cx, cy",
                                  "principal_point_px = [319.5, 239.5]  # cx, cy\ndistortion_k = [-0.1, 0.0]")
    text = text.replace("split_ratio = 0.5", "split_ratio = 0.5\nrefraction_l_mm = 1.9\nrefraction_m_mm = 1.02")
    text += "\n[calibration]\nrms_px = 0.5\nrms_left_px = 0.4\nrms_right_px = 0.6\nimages = 3\nkinds = \"3 sweep\"\n"
    nominal = tmp_path / "nominal.toml"
    nominal.write_text(text)
    start = load_rig(nominal)
    assert start.mirrors.refraction_l_mm == 1.9 and start.calibration.images == 3
    rig = calibrated(start)
    out = tmp_path / "build.toml"
    save_rig(rig, out, template=rig_template(nominal))
    raw = tomllib.loads(out.read_text())
    check_values(raw, rig)
    assert "distortion_k" not in raw["camera"] and "refraction_l_mm" not in raw["mirrors"]
    assert "refraction_m_mm" not in raw["mirrors"] and out.read_text().count("[calibration]") == 1
    assert load_rig(out) == rig
    assert MY_LENS in out.read_text().splitlines()


def test_a_shipped_rig_starts_from_its_file():
    """--rig misaligned: the shipped file's text is the template, so its comments stay."""
    shipped = shipped_rig_path("misaligned").read_text()
    assert rig_template("misaligned") == shipped
    rig = calibrated(load_rig("misaligned"))
    text = dumps_rig(rig, template=rig_template("misaligned"))
    comments = [line for line in shipped.splitlines() if line.startswith("#")]
    assert len(comments) >= 5 and [line for line in text.splitlines() if line.startswith("#")] == comments
    assert "distortion = [-0.1987, 0.1043, 0.00118, -0.00091, -0.0287]   # k1, k2, p1, p2, k3" in text
    check_values(tomllib.loads(text), rig)
    assert arrays_on_one_line(text)


def test_json_output_and_json_nominal(tmp_path):
    """JSON has no comments: a JSON nominal gives no template, and a JSON output ignores one."""
    rig = calibrated(load_rig("default"))
    nominal = tmp_path / "nominal.json"
    nominal.write_text(json.dumps(rig_to_dict(load_rig("default"))))
    assert rig_template(nominal) is None
    out = tmp_path / "build.json"
    save_rig(rig, out, template=nominal_text())
    check_values(json.loads(out.read_text()), rig)
    assert load_rig(out) == rig


def test_a_malformed_template_is_named():
    with pytest.raises(ValueError, match="malformed TOML rig template"):
        dumps_rig(load_rig("default"), template="[camera\n")


@pytest.mark.parametrize("edit", [
    lambda t: t + "\n[mirrors.m1]\nalong_mm = [-6.0, 14.0]\nheight_mm = [-7.0, 7.0]\n",
    lambda t: t.replace("[mirrors]\n", "[mirrors]\nm1 = {along_mm = [-6.0, 14.0], height_mm = [-7.0, 7.0]}\n"),
    lambda t: t.replace("[mirrors]\n", "[mirrors]\nm1.along_mm = [-6.0, 14.0]  # dotted\nm1.height_mm = [-7.0, 7.0]\n"),
    lambda t: t.replace("[camera]\n", "[mirrors.m1]\nalong_mm = [-6.0, 14.0]\nheight_mm = [-7.0, 7.0]\n\n[camera]\n"),
], ids=["table", "inline", "dotted", "out-of-order"])
def test_any_way_of_writing_a_table(tmp_path, edit):
    """A mirror's table written inline, with dotted keys or before its parent: the calibrated values land in
    it, and the file reads back (tomllib) as the rig."""
    nominal = tmp_path / "nominal.toml"
    nominal.write_text(edit(nominal_text()))
    rig = calibrated(load_rig(nominal))
    assert rig.mirrors.m1_extent is not None
    text = dumps_rig(rig, template=nominal.read_text())
    raw = tomllib.loads(text)
    check_values(raw, rig)
    assert raw == rig_to_dict(rig) and raw["mirrors"]["m1"]["along_mm"] == [-6.0, 14.0]
    assert MY_LENS in text.splitlines()
