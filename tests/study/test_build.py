"""Drawing builds: seeded from (seed, index) alone, within the stated distributions, applied to the nominal rig
as deviations, and a drawn build that is no rig refused in one line."""
import math

import numpy as np
import pytest

from psvs.io.params import load_rig
from psvs.study.build import apply_deviations, check_tolerance_edges, draw_build, draw_deviations, views_seed
from psvs.study.tolerances import PARAMS, tolerances_from_dict

TOL = tolerances_from_dict({"tolerances": {"mirror_tilt_deg": {"uniform": 0.2}, "mirror_shift_mm": {"uniform": 0.5},
                                           "focal_length_mm": {"normal": 0.1}, "k1": {"normal": 0.05},
                                           "box_rotation_deg": {"uniform": 0.3}}})


def test_same_seed_and_index_same_build_in_any_order():
    """Drawn in any order, the same (seed, index) gives the same build; another index or seed another."""
    nominal = load_rig("default")
    first = [draw_build(nominal, TOL, 5, i) for i in range(4)]
    again = [draw_build(nominal, TOL, 5, i) for i in (3, 1, 0, 2)]
    for (rig, dev), (rig2, dev2) in zip(first, [again[2], again[1], again[3], again[0]], strict=True):
        assert rig == rig2 and dev == dev2
    devs = [tuple(d.values()) for _, d in first] + [tuple(draw_deviations(TOL, 6, 0).values())]
    assert len(set(devs)) == 5
    assert len({views_seed(5, i) for i in range(50)}) == 50 and views_seed(5, 3) == views_seed(5, 3) >= 0


def test_a_parameter_draw_does_not_depend_on_the_others_toleranced():
    """Adding a tolerance on k2 leaves every other parameter's draw as it was (common random numbers)."""
    more = tolerances_from_dict({"tolerances": {"mirror_tilt_deg": {"uniform": 0.2},
                                                "mirror_shift_mm": {"uniform": 0.5}, "k2": {"normal": 0.1},
                                                "focal_length_mm": {"normal": 0.1}, "k1": {"normal": 0.05},
                                                "box_rotation_deg": {"uniform": 0.3}}})
    a, b = draw_deviations(TOL, 1, 9), draw_deviations(more, 1, 9)
    assert a["k2"] == 0.0 and b["k2"] != 0.0
    assert {k: v for k, v in a.items() if k != "k2"} == {k: v for k, v in b.items() if k != "k2"}


def test_draws_follow_their_distributions():
    """1000 builds: uniform +-0.2 deg stays inside and has the uniform's sigma 0.2/sqrt(3) (within 8 %);
    normal sigma 0.1 mm within 8 %; untoleranced parameters stay 0; the parameters are uncorrelated."""
    devs = [draw_deviations(TOL, 11, i) for i in range(1000)]
    tilt = np.array([d["m2_tilt_b_deg"] for d in devs])
    f = np.array([d["focal_length_mm"] for d in devs])
    assert np.abs(tilt).max() <= 0.2 and abs(tilt.std() / (0.2 / math.sqrt(3)) - 1) < 0.08
    assert abs(f.std() / 0.1 - 1) < 0.08 and abs(f.mean()) < 0.01
    assert all(d["plate_thickness_mm"] == 0.0 and d["k3"] == 0.0 for d in devs)
    assert abs(np.corrcoef(tilt, [d["m3_tilt_b_deg"] for d in devs])[0, 1]) < 0.1
    assert set(devs[0]) == set(PARAMS)


@pytest.mark.parametrize("rig_name", ["misaligned", "mv1440"])
def test_deviations_are_added_to_the_nominal_values(rig_name):
    """On a rig that already has errors and a lens, each deviation lands on its own field (degrees in the
    deviations, radians in the rig)."""
    nominal = load_rig(rig_name)
    rig, dev = draw_build(nominal, TOL, 3, 1)
    e0, e = nominal.mirrors.m3_error, rig.mirrors.m3_error
    assert math.isclose(e.tilt_rad[1], e0.tilt_rad[1] + math.radians(dev["m3_tilt_b_deg"]), abs_tol=1e-15)
    assert math.isclose(e.shift_mm, e0.shift_mm + dev["m3_shift_mm"], abs_tol=1e-12)
    assert math.isclose(rig.mirrors.box_rotation_rad[2],
                        nominal.mirrors.box_rotation_rad[2] + math.radians(dev["box_z_deg"]), abs_tol=1e-15)
    assert math.isclose(rig.camera.focal_length_mm, nominal.camera.focal_length_mm + dev["focal_length_mm"])
    assert math.isclose(rig.camera.distortion[0], nominal.camera.distortion[0] + dev["k1"])
    assert rig.camera.distortion[1:] == nominal.camera.distortion[1:]
    assert rig.camera.image_size_px == nominal.camera.image_size_px and rig.calibration is None


def test_a_drawn_build_that_is_no_rig_is_refused_in_one_line():
    nominal = load_rig("default")
    dev = dict.fromkeys(PARAMS, 0.0)
    for key, value, words in (("plate_thickness_mm", -3.5, "plate_thickness_mm"), ("split_ratio", 0.6, "split_ratio"),
                              ("m1_tilt_b_deg", 7.0, "mirrors.m1.tilt_deg")):
        with pytest.raises(ValueError, match=f"the drawn build is no rig: .*{words}") as info:
            apply_deviations(nominal, {**dev, key: value})
        assert "\n" not in str(info.value)
    for seed, index in ((-1, 0), (0, -2), (1.5, 0), (True, 0)):
        with pytest.raises(ValueError, match="must be a whole number >= 0"):
            draw_deviations(TOL, seed, index)


@pytest.mark.parametrize("table, key", [({"mirror_tilt_deg": {"uniform": 20.0}}, "m1_tilt_a_deg"),
                                        ({"box_rotation_deg": {"normal": 3.5}}, "box_x_deg"),
                                        ({"split_ratio": {"uniform": 0.6}}, "split_ratio")])
def test_a_tolerance_whose_draws_are_no_rig_is_refused_before_the_study(table, key):
    """Issue 41's trial: mirror tilts of +-20 deg (the rig file allows 6) ran a study of 0 builds and exited
    0; a tolerance whose edge (a uniform's half-width, a normal's 2 sigma) is no rig even alone is refused."""
    rig = load_rig("default")
    with pytest.raises(ValueError, match=rf"^tolerances: {key} \{{ \w+ = [\d.]+ \}}: a build at its .* is no rig "
                                         r"\(.*\); a tolerance must draw builds of the rig$"):
        check_tolerance_edges(rig, tolerances_from_dict({"tolerances": table}))
    check_tolerance_edges(rig, TOL)                                  # the shipped kind of tolerances pass
    check_tolerance_edges(rig, tolerances_from_dict({"tolerances": {"box_rotation_deg": {"normal": 2.9}}}))
