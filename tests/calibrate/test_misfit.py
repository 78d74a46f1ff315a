"""psvs.calibrate.misfit: the detections' noise read from a bundle's residuals (second differences along the
card's rows and columns) against planted noise and planted smooth misfits; the refusal of a fit beyond it."""
from types import SimpleNamespace

import numpy as np
import pytest

from psvs.calibrate.bundle import GridView
from psvs.calibrate.misfit import MISFIT_RATIO, check_misfit, lattice_noise_px
from psvs.errors import MeasurementError


def card_views(n_views=12, rows=4, cols=6, spacing=14.0):
    """Views of a rows x cols card centred on its middle (its coordinates half a spacing off the lattice)."""
    x, y = np.meshgrid((np.arange(cols) - (cols - 1) / 2) * spacing, (np.arange(rows) - (rows - 1) / 2) * spacing)
    obj = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    return [GridView(f"v{k}", obj, np.zeros((x.size, 2)), np.zeros((x.size, 2))) for k in range(n_views)], obj


def bundle_of(residuals):
    r = np.concatenate([np.concatenate(v) for v in residuals.values()])
    return SimpleNamespace(residuals=residuals, rms_px=float(np.sqrt(np.mean(r ** 2))))


@pytest.mark.parametrize("sigma", [0.02, 0.15])
def test_the_noise_of_white_detections_is_read_back(sigma):
    grids, obj = card_views()
    rng = np.random.default_rng(3)
    res = {g.name: (rng.normal(0, sigma, (len(obj), 2)), rng.normal(0, sigma, (len(obj), 2))) for g in grids}
    noise, n = lattice_noise_px(grids, res)
    assert n == 12 * 2 * (4 * 4 + 2 * 6) and abs(noise - sigma) <= 0.1 * sigma, (noise, n)
    check_misfit(bundle_of(res), grids, "the fit")           # noise alone: no refusal, at any level


def test_a_smooth_misfit_is_refused_and_its_noise_still_read():
    """A view turned about its centre and a scale error leave residuals linear over the card: the second
    differences cancel them and read the noise beneath; the RMS then stands far above it."""
    grids, obj = card_views()
    rng = np.random.default_rng(4)
    u, v = obj[:, 0] / 35.0, obj[:, 1] / 21.0
    field = 0.25 * np.column_stack([u - 0.5 * v, v + 0.3 * u])
    res = {g.name: (field * (k % 3 - 1) + rng.normal(0, 0.03, field.shape), rng.normal(0, 0.03, field.shape))
           for k, g in enumerate(grids)}
    noise, _ = lattice_noise_px(grids, res)
    assert abs(noise - 0.03) <= 0.004
    b = bundle_of(res)
    assert b.rms_px > MISFIT_RATIO * noise
    with pytest.raises(MeasurementError, match=r"the fit does not fit its views: reprojection RMS 0\.1\d\d px against "
                                               r"the detections' own noise 0\.03\d px \(read from 672 second"):
        check_misfit(b, grids, "the fit")
    # below the floor a pattern is not refused: what it leaves no use of the rig would see
    small = {k: tuple(a * 0.1 for a in v) for k, v in res.items()}
    check_misfit(bundle_of(small), grids, "the fit")


def test_too_few_differences_are_not_tested():
    grids, obj = card_views(n_views=1, rows=2, cols=3)
    res = {grids[0].name: (np.full((6, 2), 1.0), np.full((6, 2), -1.0))}
    assert lattice_noise_px(grids, res)[1] == 4          # 2 rows x 1 triple x 2 views; columns too short
    check_misfit(bundle_of(res), grids, "the fit")
