"""Files that arrive as text (the web page's uploads): a rig file and mount.toml read from their text give what
the file readers give, a byte-order mark aside; bad text is one ValueError naming where it came from."""
from __future__ import annotations

import pytest

from psvs.io.params import load_rig, rig_from_text
from psvs.mount.files import mount_toml, read_mount_text
from psvs.mount.layout import MountParams, mount_layout
from psvs.mount.report import check_same_design, turn_instruction
from psvs.mount.seats import seats_for
from psvs.optics.design import design_mirrors
from psvs.rigs import SHIPPED, shipped_rig_path


@pytest.mark.parametrize("name", SHIPPED)
def test_rig_from_text_is_load_rig(name):
    text = shipped_rig_path(name).read_text(encoding="utf-8")
    assert rig_from_text(text) == load_rig(shipped_rig_path(name))
    assert rig_from_text("\ufeff" + text) == load_rig(shipped_rig_path(name))      # a spreadsheet's BOM


def test_mount_text_gives_the_seats_it_was_written_from():
    """mount.toml's text (written without the CAD extra: the layout alone) reads back as the seats on the
    designed mirrors with the mount's pitch and glass."""
    design = design_mirrors(load_rig(shipped_rig_path("clear")), search=False)
    params = MountParams(pitch_mm=0.35)
    params_back, seats = read_mount_text(mount_toml(mount_layout(design, params), {}))
    assert params_back == params
    assert seats == seats_for(design.rig, pitch_mm=0.35, glass_mm=params.glass_mm, m1_border_mm=params.m1_border_mm)


@pytest.mark.parametrize("text, says", [
    ("[seats\n", "upload.toml: malformed TOML"),
    ("seats = 3\n", "upload.toml: not a mount file psvs wrote (missing 'mount')"),
    ("[mount.params]\n[seats.m1]\npivot_st_mm = [0, 0]\n", "upload.toml: not a mount file psvs wrote (missing"),
    ("[mount]\nparams = 3\n[seats]\n", "upload.toml: not a mount file psvs wrote"),
])
def test_bad_mount_text_is_one_line(text, says):
    with pytest.raises(ValueError) as info:
        read_mount_text(text, "upload.toml")
    assert str(info.value).startswith(says) and "\n" not in str(info.value)


def test_bad_rig_text_names_where():
    with pytest.raises(ValueError, match=r"^uploaded: malformed TOML"):
        rig_from_text("[camera", "uploaded")
    with pytest.raises(ValueError, match=r"^uploaded: missing key camera.pixel_pitch_mm"):
        rig_from_text("[camera]\nfocal_length_mm = 8\nimage_size_px = [640, 480]\n[mirrors]\n", "uploaded")


def test_same_design_names_the_design_and_instructions():
    with pytest.raises(ValueError, match=r"the calibrated rig and the design \(clear\) are not one design: "
                                         r"m1_axis_distance_mm 16 vs 22 mm"):
        check_same_design(load_rig("mv1440_misaligned"), load_rig("clear"), "the design (clear)")
    assert turn_instruction(0.0, "none") == "leave"
    assert turn_instruction(-1.1875, "counter-clockwise") == "1 3/16 turns counter-clockwise"
