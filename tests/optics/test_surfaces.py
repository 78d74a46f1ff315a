import math

import numpy as np
import pytest

from psvs.optics.plate import derived_refraction_terms, plate_shift_derivative_mm, plate_shift_mm
from psvs.optics.surfaces import refract
from psvs.optics.trace import trace_pixels


def test_snell_law_holds():
    """n1 sin(i) = n2 sin(t), and t stays in the plane of incidence."""
    rng = np.random.default_rng(0)
    normal = np.array([1.0, 0, -1.0]) / math.sqrt(2)
    d = rng.normal(size=(200, 3)) + [0, 0, 3]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t, ok = refract(d, normal, 1 / 1.52)
    assert ok.all()
    sin_i = np.linalg.norm(np.cross(d, normal), axis=1)
    sin_t = np.linalg.norm(np.cross(t, normal), axis=1)
    np.testing.assert_allclose(sin_i, 1.52 * sin_t, atol=1e-12)
    np.testing.assert_allclose(np.einsum("ij,ij->i", np.cross(d, normal), t), 0, atol=1e-12)
    back, _ = refract(t, normal, 1.52)
    np.testing.assert_allclose(back, d, atol=1e-12)  # a parallel plate keeps the direction


def test_total_internal_reflection_flagged():
    normal = np.array([0.0, 0.0, 1.0])
    d = np.array([[math.sin(0.8), 0.0, math.cos(0.8)]])  # 45.8 deg inside glass > critical 41.1 deg
    out, ok = refract(d, normal, 1.52)
    assert not ok[0] and np.isnan(out).all()


@pytest.mark.parametrize("theta_deg", [0.0, 20.0, 45.0, 60.0])
def test_plate_shift_formula(theta_deg):
    """Textbook check: delta = d sin(theta - theta_t) / cos(theta_t); zero at normal incidence."""
    th = math.radians(theta_deg)
    th_t = math.asin(math.sin(th) / 1.52)
    assert plate_shift_mm(th, 3.0, 1.52) == pytest.approx(3 * math.sin(th - th_t) / math.cos(th_t), abs=1e-12)
    h = 1e-6
    num = (plate_shift_mm(th + h, 3.0, 1.52) - plate_shift_mm(th - h, 3.0, 1.52)) / (2 * h)
    assert plate_shift_derivative_mm(th, 3.0, 1.52) == pytest.approx(num, abs=1e-7)


@pytest.mark.parametrize("u", [0.0, 160.0, 319.5, 500.0, 639.0])
def test_traced_left_ray_offset_is_plate_shift(rig, u):
    """On the middle row the traced left ray is O1's ray moved by -delta / cos(alpha) in X on z = z_v."""
    rays = trace_pixels([[u, 239.5]], rig, "left")
    o, d = rays.origins_mm[0], rays.dirs[0]
    x_at_zv = o[0] + (rig.virtual_z_mm - o[2]) * d[0] / d[2]
    alpha = math.atan((u - 319.5) * 0.01 / 11.3)
    delta = plate_shift_mm(math.pi / 4 + alpha, 3.0, 1.52)
    assert x_at_zv == pytest.approx(-50.0 - delta / math.cos(alpha), abs=1e-10)


def test_derived_refraction_terms_are_first_order_of_traced_shift(rig):
    """m = -s(0) and l = -f ds/dx_l at x_l = 0, with s the traced X offset on z = z_v."""
    def s(x_mm):
        rays = trace_pixels([[319.5 + x_mm / 0.01, 239.5]], rig, "left")
        o, d = rays.origins_mm[0], rays.dirs[0]
        return o[0] + (rig.virtual_z_mm - o[2]) * d[0] / d[2] + 50.0
    h = 1e-4
    l_mm, m_mm = derived_refraction_terms(rig)
    assert m_mm == pytest.approx(-s(0.0), abs=1e-10)
    assert l_mm == pytest.approx(-11.3 * (s(h) - s(-h)) / (2 * h), abs=1e-6)


def test_zero_plate_has_no_refraction_terms(rig):
    assert derived_refraction_terms(rig.replace(plate_thickness_mm=0.0)) == (0.0, 0.0)
