import numpy as np
import pytest

from psvs.measure.equations import project_eq9_10, x_eq11, x_eq13, y_eq14, z_eq12, z_eq15


def test_eq9_10_then_eq11_14_round_trip():
    """Project with eqs. (9)-(10), recover with eqs. (11)-(14) to 1e-9 mm; eq. (11) = eq. (13)."""
    rng = np.random.default_rng(0)
    p = np.column_stack([rng.uniform(-200, 200, 500), rng.uniform(-150, 150, 500), rng.uniform(100, 3000, 500)])
    f, b = 11.3, 100.0
    xl, xr, y = project_eq9_10(p, f, b)
    z = z_eq12(xl, xr, f, b)
    np.testing.assert_allclose(z, p[:, 2], atol=1e-9)
    np.testing.assert_allclose(x_eq13(xr, z, f, b), p[:, 0], atol=1e-9)
    np.testing.assert_allclose(x_eq11(xl, xr, b), p[:, 0], atol=1e-9)
    np.testing.assert_allclose(y_eq14(y, z, f, b), p[:, 1], atol=1e-9)


def test_eq12_by_hand():
    """Disparity 1 mm with b f = 1130 mm^2: z = 1130 - 50 = 1080 mm."""
    assert z_eq12(0.5, -0.5, 11.3, 100.0) == pytest.approx(1080.0, abs=1e-12)


def test_eq15_reduces_to_eq12_and_adds_terms():
    xl, xr = np.array([0.7, -0.2]), np.array([-0.3, -0.9])
    np.testing.assert_allclose(z_eq15(xl, xr, 11.3, 100.0, 0.0, 0.0), z_eq12(xl, xr, 11.3, 100.0), atol=1e-12)
    # by hand: (b f + x_l l + f m) / D - b/2 with D = 1, l = 2, m = 1: 1130 + 1.4 + 11.3 - 50
    assert z_eq15(0.7, -0.3, 11.3, 100.0, 2.0, 1.0) == pytest.approx(1092.7, abs=1e-9)


def test_general_virtual_depth():
    """With z_v given, "z + b/2" becomes "z - z_v" everywhere."""
    p = np.array([[10.0, -20.0, 700.0]])
    xl, xr, y = project_eq9_10(p, 11.3, 100.0, z_v=-42.0)
    z = z_eq12(xl, xr, 11.3, 100.0, z_v=-42.0)
    assert z[0] == pytest.approx(700.0, abs=1e-9)
    assert x_eq13(xr, z, 11.3, 100.0, z_v=-42.0)[0] == pytest.approx(10.0, abs=1e-9)


@pytest.mark.parametrize("xl, xr", [(0.1, 0.1), (-0.2, 0.3), (np.nan, 0.0)])
def test_non_positive_disparity_is_nan(xl, xr):
    assert np.isnan(z_eq12(xl, xr, 11.3, 100.0))
    assert np.isnan(z_eq15(xl, xr, 11.3, 100.0, 1.8, 1.0))
    assert np.isnan(x_eq11(xl, xr, 100.0))
