import numpy as np
import pytest

from psvs.match.subpixel import refine_columns


@pytest.mark.parametrize("x0", [40.0, 40.25, 40.5, 40.8])
def test_step_edge_position(x0):
    """A blurred step whose half-level crossing is at x0 (px) is found to 0.08 px (linear interpolation of
    the curved erf profile between samples costs up to ~0.06 px)."""
    from scipy.special import erf
    u = np.arange(100, dtype=float)
    row = 30 + 150 * 0.5 * (1 + erf((u - x0) / (1.2 * np.sqrt(2))))
    img = np.tile(row, (20, 1))
    out = refine_columns(img, np.array([[int(x0), 10.0]]))
    assert out[0, 0] == pytest.approx(x0, abs=0.08)


def test_horizontal_edges_keep_integer_positions():
    img = np.zeros((40, 40))
    img[20:] = 200.0
    out = refine_columns(img, np.array([[15.0, 19.0]]))
    assert out[0, 0] == 15.0


def test_sign_picks_the_edge_of_a_thin_stripe_that_steps_the_right_way():
    """A dark stripe 2.5 px wide between a bright (200) and a dimmer (120) level, box-sampled and blurred
    (sigma 0.6 px): the stripe's falling edge is the steeper one. Asked for the rising edge (at 43.8 px,
    pixel centres), the refinement finds it within 0.15 px (the low and high levels come from their own
    sides of it); without the sign it lands on the falling edge (41.3 px)."""
    from scipy.ndimage import gaussian_filter1d
    fine = np.arange(0, 100, 0.01) - 0.5                      # pixel k covers [k - 0.5, k + 0.5)
    prof = gaussian_filter1d(np.where(fine < 41.3, 200.0, np.where(fine < 43.8, 20.0, 120.0)), 60)
    img = np.tile(prof.reshape(100, 100).mean(axis=1), (20, 1))
    px = np.array([[43.0, 10.0]])
    assert refine_columns(img, px, sign=np.array([1]))[0, 0] == pytest.approx(43.8, abs=0.15)
    assert refine_columns(img, px)[0, 0] == pytest.approx(41.3, abs=0.4)
