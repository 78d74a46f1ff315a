"""The bundle adjustment's rig parameters are read and set by name: a rig with every calibrated parameter at
a different value goes to a vector and back, each parameter checked against the rig's own field (not the
vector's order), also with RIG_PARAMS in another order."""
import math

import numpy as np
import pytest
from scipy.optimize import least_squares

from psvs import default_rig
from psvs.calibrate import bundle
from psvs.calibrate.bundle import PRIOR_SIGMA, RIG_PARAMS, rig_from_values, rig_from_vector, rig_values, rig_vector
from psvs.optics.rig import MirrorError


def distinct_rig():
    """The default rig with each of the 26 calibrated parameters set to a value no other one has."""
    rig = default_rig().replace(focal_length_mm=11.41, principal_point_px=(321.7, 238.2), pixel_pitch_mm=(0.01, 0.0101),
                                distortion=(-0.21, 0.07, 1.2e-3, -8e-4, -0.015), plate_thickness_mm=2.9,
                                baseline_mm=101.3, box_rotation_rad=(1.1e-3, -2.2e-3, 3.3e-3))
    return rig.with_errors({"m1": MirrorError((math.radians(0.11), math.radians(-0.12)), 0.31),
                            "m2": MirrorError((math.radians(0.13), math.radians(-0.14)), -0.32),
                            "m3": MirrorError((math.radians(0.15), math.radians(-0.16)), 0.33),
                            "m4": MirrorError((math.radians(0.17), math.radians(-0.18)), -0.34)})


def fields(rig) -> dict:
    """Each calibrated parameter read from the rig's own fields, written out here by hand."""
    c, m = rig.camera, rig.mirrors
    out = {"focal_length_mm": c.focal_length_mm, "cx_px": c.principal_point_px[0], "cy_px": c.principal_point_px[1],
           "pixel_aspect": c.pixel_pitch_mm[1] / c.pixel_pitch_mm[0],
           "k1": c.distortion[0], "k2": c.distortion[1], "p1": c.distortion[2], "p2": c.distortion[3],
           "k3": c.distortion[4], "plate_thickness_mm": m.plate_thickness_mm, "baseline_mm": m.baseline_mm,
           "box_x_rad": m.box_rotation_rad[0], "box_y_rad": m.box_rotation_rad[1], "box_z_rad": m.box_rotation_rad[2]}
    for name, err in (("m1", m.m1_error), ("m2", m.m2_error), ("m3", m.m3_error), ("m4", m.m4_error)):
        out[f"{name}_tilt_a_rad"] = err.tilt_rad[0]
        out[f"{name}_tilt_b_rad"] = err.tilt_rad[1]
        out[f"{name}_shift_mm"] = err.shift_mm
    return out


def check_round_trip():
    rig = distinct_rig()
    want = fields(rig)
    assert set(want) == set(RIG_PARAMS) and len(set(want.values())) == len(RIG_PARAMS)   # all different
    vec = rig_vector(rig)
    assert vec.shape == (len(RIG_PARAMS),)
    for k, name in enumerate(bundle.RIG_PARAMS):
        assert vec[k] == want[name], name
    assert rig_values(rig) == want
    back = rig_from_vector(vec, default_rig())
    assert fields(back) == want
    assert fields(rig_from_values(want, default_rig())) == want
    # the fields calibration does not touch stay the start rig's; the pixel's width too (f carries the scale)
    start = default_rig()
    assert back.camera.pixel_pitch_mm[0] == start.camera.pixel_pitch_mm[0]
    assert back.camera.image_size_px == start.camera.image_size_px
    assert back.mirrors.angle_rad == start.mirrors.angle_rad
    assert back.mirrors.m1_axis_distance_mm == start.mirrors.m1_axis_distance_mm


def test_round_trip_by_name():
    check_round_trip()


def test_round_trip_survives_another_order(monkeypatch):
    monkeypatch.setattr(bundle, "RIG_PARAMS", tuple(reversed(RIG_PARAMS)))
    vec = bundle.rig_vector(distinct_rig())
    assert vec[0] == distinct_rig().mirrors.box_rotation_rad[2]       # box_z_rad now comes first
    check_round_trip()


def test_every_parameter_has_a_prior_and_a_step():
    assert set(PRIOR_SIGMA) == set(RIG_PARAMS)
    assert set(RIG_PARAMS) <= set(bundle.DIFF_STEP)


def test_bad_vectors_name_the_problem():
    with pytest.raises(ValueError, match=r"a rig vector holds 26 parameters, got shape \(25,\)"):
        rig_from_vector(np.zeros(25), default_rig())
    values = fields(distinct_rig())
    del values["m3_shift_mm"]
    with pytest.raises(ValueError, match="rig parameter m3_shift_mm is missing"):
        rig_from_values(values, default_rig())


def test_verdicts_follow_scipys_status():
    """Each status least_squares documents gets its sentence; a fit stopped at max_nfev says it did not converge."""
    sol = least_squares(lambda x: x - 3.0, np.zeros(2))
    assert sol.status in (1, 2, 3, 4) and bundle.solver_verdict(sol.status, sol.nfev).startswith("converged: ")
    stopped = least_squares(lambda x: np.exp(x) - 3.0 + x ** 3, np.full(2, 5.0), max_nfev=1)
    assert stopped.status == 0
    assert (bundle.solver_verdict(stopped.status, stopped.nfev)
            == "did not converge: stopped at the evaluation limit (1 evaluations)")
    assert bundle.solver_verdict(7, 3) == "ended with solver status 7 (3 evaluations)"
