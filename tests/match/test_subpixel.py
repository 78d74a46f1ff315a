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
