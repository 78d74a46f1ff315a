"""Fig. 7c/d and Fig. 8 as written: titles inside the figure, a legend naming every pair, PNGs that decode."""
import cv2
import matplotlib
import numpy as np
import pytest

from psvs import default_rig
from psvs.match.correspondence import match_image
from psvs.match.figures import disparity_figure, views_figure, write_figures
from psvs.simulate.builtin import builtin_scene
from psvs.simulate.render import render

matplotlib.use("Agg")


@pytest.fixture(scope="module")
def matched():
    img = render(builtin_scene("fig5b"), default_rig(), seed=1).image
    return match_image(img, default_rig()), img


def inside(fig, artist) -> bool:
    box, page = artist.get_window_extent(fig.canvas.get_renderer()), fig.bbox
    return box.x0 >= page.x0 - 0.5 and box.x1 <= page.x1 + 0.5 and box.y0 >= page.y0 - 0.5 and box.y1 <= page.y1 + 0.5


def test_fig7_titles_fit_and_the_legend_names_each_pair(matched):
    res, img = matched
    fig = views_figure(res, img)
    fig.canvas.draw()
    for ax in fig.axes:
        assert inside(fig, ax.title), ax.get_title()
    legend = fig.axes[1].get_legend()
    assert [t.get_text() for t in legend.get_texts()] == [
        f"edge {k}: {len(p)} px, Z {p.median_z_mm():.0f} mm" for k, p in enumerate(res.pairs)]
    assert inside(fig, legend)


def test_fig8_has_a_legend(matched):
    res, _ = matched
    fig = disparity_figure(res)
    fig.canvas.draw()
    legend = fig.axes[0].get_legend()
    assert len(legend.get_texts()) == len(res.pairs) >= 4 and inside(fig, fig.axes[0].title)


def test_written_pngs_decode_at_the_figure_size(matched, tmp_path):
    res, img = matched
    p7, p8 = write_figures(tmp_path, res, img)
    a, b = cv2.imread(str(p7)), cv2.imread(str(p8))
    assert a.shape == (520, 1200, 3) and b.shape == (600, 750, 3)     # figsize x 100 dpi
    assert (np.abs(a.astype(int) - 255).sum(axis=2) > 100).mean() > 0.02   # not blank
