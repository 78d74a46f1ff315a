"""Figures like the paper's: Fig. 7c/d (the two views' edges in their colours) and Fig. 8 (disparity map)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from psvs.io.atomic import write_atomic
from psvs.match.correspondence import MatchResult


def _save(fig, path: Path) -> None:
    import io
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    write_atomic(path, buf.getvalue())


def write_figures(folder, res: MatchResult, image: np.ndarray) -> list[Path]:
    """Write fig7_views.png (left and right views' matched edges, inverted, one colour per pair) and
    fig8_disparity.png (3-D plot of disparity against pixel position) into ``folder``."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"figures folder does not exist: {folder}")
    h, w = image.shape
    colours = plt.get_cmap("tab10")
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.6))
    for ax, side, title in ((axes[0], "left_px", "(c) left view"), (axes[1], "right_px", "(d) right view")):
        ax.imshow(~res.edges, cmap="gray", vmin=0, vmax=1, alpha=0.25)
        for k, p in enumerate(res.pairs):
            pts = getattr(p, side)
            ax.scatter(pts[:, 0], pts[:, 1], s=1.5, color=colours(k % 10), label=f"edge {k}")
        ax.set_xlim(0, w)
        ax.set_ylim(h, 0)
        ax.set_title(f"{title}: matched edges (Fig. 7c/d)")
        ax.set_xlabel("u (px)")
        ax.set_ylabel("v (px)")
    fig.tight_layout()
    p7 = folder / "fig7_views.png"
    _save(fig, p7)
    plt.close(fig)

    fig = plt.figure(figsize=(7, 5.5))
    ax = fig.add_subplot(projection="3d")
    for k, p in enumerate(res.pairs):
        ax.scatter(p.left_px[:, 0], p.left_px[:, 1], p.disparity_px, s=2, color=colours(k % 10))
    ax.set_xlabel("u (px)")
    ax.set_ylabel("v (px)")
    ax.set_zlabel("disparity (px)")
    ax.set_title("Disparity map (Fig. 8)")
    p8 = folder / "fig8_disparity.png"
    _save(fig, p8)
    plt.close(fig)
    return [p7, p8]
