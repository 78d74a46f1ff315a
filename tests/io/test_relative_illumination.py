"""The lens's relative illumination in a rig file (camera.relative_illumination = [a2, a4],
psvs.optics.illumination, docs/rig_file.md): its value by hand, its bounds at load time, and a round trip by
value through the writer (tomlkit, comments kept) and tomllib."""
import copy
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from psvs.io.params import dumps_rig, load_rig, rig_from_dict, rig_template
from psvs.optics.illumination import corner_rho2, illumination_map, relative_illumination
from psvs.optics.rig import Camera
from psvs.optics.window import roi_rig

ROOT = Path(__file__).resolve().parents[2]
MISALIGNED = tomllib.loads((ROOT / "src" / "psvs" / "rigs" / "misaligned.toml").read_text())


def _with(ri, **camera):
    data = copy.deepcopy(MISALIGNED)
    data["camera"]["relative_illumination"] = ri
    data["camera"].update(camera)
    return data


def test_value_by_hand():
    """Pixel (u, v) = (cx + 300, cy + 400) at 0.005 mm pitch: h = hypot(1.5, 2.0) = 2.5 mm, f = 5 mm, so
    rho = 0.5 and RI = 1 + a2 / 4 + a4 / 16; on the axis RI = 1."""
    cam = Camera(focal_length_mm=5.0, pixel_pitch_mm=(0.005, 0.005), image_size_px=(1000, 1000),
                 principal_point_px=(400.0, 300.0), relative_illumination=(-0.8, -1.6))
    ri = relative_illumination([[700.0, 700.0], [400.0, 300.0], [100.0, 300.0]], cam)
    np.testing.assert_allclose(ri, [1 - 0.2 - 0.1, 1.0, 1 - 0.8 * 0.09 - 1.6 * 0.09 ** 2], rtol=0, atol=1e-15)
    m = illumination_map(cam)
    assert m.shape == (1000, 1000)
    assert m[700, 700] == pytest.approx(0.7, abs=1e-15) and m[300, 400] == 1.0
    flat = Camera(focal_length_mm=5.0, image_size_px=(64, 48), principal_point_px=(31.5, 23.5))
    assert not flat.vignetted and np.all(illumination_map(flat) == 1.0)


def test_a_sensor_window_keeps_the_same_fall_off():
    """rho = h / f is the lens's: a camera read through a window (its own size and principal point) sees the
    same RI at the same place on the sensor."""
    rig = load_rig("mv1440_misaligned")
    win, v0 = roi_rig(rig, 200, 300)
    assert v0 == 300
    full = illumination_map(rig.camera)
    np.testing.assert_allclose(illumination_map(win.camera), full[300:500], rtol=0, atol=1e-12)


def test_the_shipped_machine_vision_rigs():
    """mv1440: the datasheet's 75 % in the corners; mv1440_misaligned: ~30 % fall-off there."""
    for name, corner in (("mv1440", 0.75), ("mv1440_misaligned", 0.70)):
        m = illumination_map(load_rig(name).camera)
        assert m.max() <= 1.0 and m.max() > 0.9999
        assert min(m[0, 0], m[0, -1], m[-1, 0], m[-1, -1]) == pytest.approx(corner, abs=0.01), name
    assert not load_rig("misaligned").camera.vignetted


# misaligned's camera: f = 11.413 mm, 640 x 480 px at 0.01 mm, principal point (324.3, 236.6); its farthest
# corner's outer edge is (324.8, 242.9) px from it: h^2 = 3.248^2 + 2.429^2 mm^2, rho^2 = h^2 / f^2
RHO2 = (3.248 ** 2 + 2.429 ** 2) / 11.413 ** 2


def test_corner_rho_by_hand():
    assert corner_rho2(rig_from_dict(_with([-1.0, 0.0])).camera) == pytest.approx(RHO2, rel=1e-12)


@pytest.mark.parametrize("ri, camera, inside", [
    ([-0.95 / RHO2 + 0.01, 0.0], {}, True),         # RI = 0.05 + 0.01 rho^2 in the corner: just enough light
    ([-0.95 / RHO2 - 0.01, 0.0], {}, False),        # just under 5 %
    ([1e-3, 0.0], {}, False),                        # more light off the axis than on it
    ([-1.0, 1e-3], {}, True),                        # a4 > 0, still falling everywhere on the sensor
    ([-50.0, 50.0], {"focal_length_mm": 2000.0}, True),   # a long lens: rho tiny, any term inside its bound
    ([-50.01, 50.0], {"focal_length_mm": 2000.0}, False),
    ([-50.0, 50.01], {"focal_length_mm": 2000.0}, False),
])
def test_bounds_at_load_time(ri, camera, inside):
    data = _with(ri, **camera)
    if inside:
        rig = rig_from_dict(data)
        assert rig.camera.relative_illumination == tuple(ri)
        return
    with pytest.raises(ValueError, match=r"^camera\.relative_illumination") as info:
        rig_from_dict(data)
    msg = str(info.value)
    assert "\n" not in msg
    assert ("-50..50" in msg) if abs(ri[0]) > 50 or abs(ri[1]) > 50 else ("0.05..1" in msg and "rho = 0.355" in msg)


@pytest.mark.parametrize("bad, match", [
    ([-1.0], "relative_illumination"), ("flat", "relative_illumination"), ([-1.0, math.nan], "relative_illumination"),
])
def test_malformed_values_are_named(bad, match):
    with pytest.raises((ValueError, TypeError), match=match):
        rig_from_dict(_with(bad))


def test_round_trip_by_value_through_the_writer_and_tomllib():
    """mv1440's file as the template: a changed RI is replaced in place (its comment kept) and reads back by
    value with tomllib; a flat lens drops the key; the paper's rig gains it at the end of [camera]."""
    rig = load_rig("mv1440")
    template = rig_template("mv1440")
    new = rig.replace(relative_illumination=(-1.234567890123, -0.5))
    text = dumps_rig(new, template=template)
    assert "relative_illumination = [-1.234567890123, -0.5]   # a2, a4: RI = 1 + a2 rho^2" in text
    back = rig_from_dict(tomllib.loads(text))
    assert back == new and back.camera.relative_illumination == (-1.234567890123, -0.5)
    assert dumps_rig(back, template=text) == text
    assert text.splitlines()[:8] == template.splitlines()[:8]     # the file's header comments stay
    flat = dumps_rig(rig.replace(relative_illumination=(0.0, 0.0)), template=template)
    assert "relative_illumination" not in flat
    assert rig_from_dict(tomllib.loads(flat)).camera.relative_illumination == (0.0, 0.0)
    gained = dumps_rig(load_rig("default").replace(relative_illumination=(-2.0, 3.0)),
                       template=rig_template("default"))
    camera = tomllib.loads(gained)["camera"]
    assert list(camera)[-1] == "relative_illumination" and camera["relative_illumination"] == [-2.0, 3.0]
    assert rig_from_dict(tomllib.loads(dumps_rig(new))) == new and "relative_illumination" in dumps_rig(new, "json")
