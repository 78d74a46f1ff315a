"""Figures like the paper's: Fig. 7c/d (the two views' edges in their colours) and Fig. 8 (disparity map)."""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from psvs.io.atomic import write_atomic
from psvs.match.correspondence import MatchResult


def _label(k: int, p) -> str:
    z = p.median_z_mm()
    return f"edge {k}: {len(p)} px, Z {z:.0f} mm" if np.isfinite(z) else f"edge {k}: {len(p)} px"


def views_figure(res: MatchResult, image: np.ndarray):
    """Fig. 7c/d: the left and right views' matched edges over the (inverted) edge map, one colour per pair,
    with a legend naming each pair's size and median depth. Returns the matplotlib figure."""
    import matplotlib.pyplot as plt
    h, w = image.shape
    colours = plt.get_cmap("tab10")
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.2), layout="constrained")
    for ax, side, title in ((axes[0], "left_px", "(c) left view"), (axes[1], "right_px", "(d) right view")):
        ax.imshow(~res.edges, cmap="gray", vmin=0, vmax=1, alpha=0.25)
        for k, p in enumerate(res.pairs):
            pts = getattr(p, side)
            ax.scatter(pts[:, 0], pts[:, 1], s=1.5, color=colours(k % 10), label=_label(k, p))
        ax.set_xlim(0, w)
        ax.set_ylim(h, 0)
        ax.set_title(f"{title}: matched edges (Fig. 7c/d)")
        ax.set_xlabel("u (px)")
        ax.set_ylabel("v (px)")
    if res.pairs:
        axes[1].legend(loc="upper right", fontsize=7, markerscale=4)
    return fig


def disparity_figure(res: MatchResult):
    """Fig. 8: disparity (px) against the left pixel (u, v), one colour per pair, with a legend."""
    import matplotlib.pyplot as plt
    colours = plt.get_cmap("tab10")
    fig = plt.figure(figsize=(7.5, 6), layout="constrained")
    ax = fig.add_subplot(projection="3d")
    for k, p in enumerate(res.pairs):
        ax.scatter(p.left_px[:, 0], p.left_px[:, 1], p.disparity_px, s=2, color=colours(k % 10),
                   label=_label(k, p))
    ax.set_xlabel("u (px)")
    ax.set_ylabel("v (px)")
    ax.set_zlabel("disparity (px)")
    ax.set_title("Disparity map (Fig. 8)")
    if res.pairs:
        ax.legend(loc="upper left", fontsize=7, markerscale=4)
    return fig


def write_figures(folder, res: MatchResult, image: np.ndarray) -> list[Path]:
    """Write fig7_views.png (:func:`views_figure`) and fig8_disparity.png (:func:`disparity_figure`) into
    ``folder``, atomically; return their paths."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"figures folder does not exist: {folder}")
    out = []
    for name, fig in (("fig7_views.png", views_figure(res, image)), ("fig8_disparity.png", disparity_figure(res))):
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=100)
        plt.close(fig)
        write_atomic(folder / name, buf.getvalue())
        out.append(folder / name)
    return out
