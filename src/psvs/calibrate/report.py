"""A calibration's report (``psvs calibrate --report DIR``): every detection's residual as numbers
(``residuals.csv``) and over the image (``residuals.png``), and the map of the vertical disagreement between
the two views of a point that the calibrated rig predicts (``vertical_disagreement.png``)."""
from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from psvs.calibrate.bundle import BundleResult
from psvs.io.atomic import write_atomic
from psvs.optics.project import project_points
from psvs.optics.rig import Rig
from psvs.optics.trace import trace_pixels


def vertical_disagreement(rig: Rig, depth_mm: float, step_px: int = 16) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u, v, dv): left-view pixels on a grid (step_px apart) and, for each, v_right - v_left (px) of the
    point it sees at ``depth_mm`` -- how far a twin sits off its row; NaN where the point leaves the image."""
    w, h = rig.camera.image_size_px
    u, v = np.meshgrid(np.arange(0, w, step_px, dtype=float), np.arange(0, h, step_px, dtype=float))
    uv = np.column_stack([u.ravel(), v.ravel()])
    rays = trace_pixels(uv, rig, "left")
    t = (depth_mm - rays.origins_mm[:, 2]) / rays.dirs[:, 2]
    pts = rays.origins_mm + t[:, None] * rays.dirs
    right, ok = project_points(pts, rig, "right")
    ok &= rays.valid & (right[:, 0] >= 0) & (right[:, 0] <= w - 1)
    dv = np.where(ok, right[:, 1] - uv[:, 1], np.nan)
    return u, v, dv.reshape(u.shape)


RESIDUAL_COLUMNS = ("image", "view", "u_px", "v_px", "du_px", "dv_px")


def residuals_csv(res: BundleResult) -> str:
    """``residuals.csv``'s text: one row per detection (image, view 'left' or 'right', the detected centre
    u_px, v_px and its residual du_px, dv_px = projection - detection, px), numbers as Python's ``repr`` so
    they read back exactly; the RMS of the residuals is the calibration's."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(RESIDUAL_COLUMNS)
    for name in res.residuals:
        for k, view in enumerate(("left", "right")):
            for (u, v), (du, dv) in zip(res.observed[name][k], res.residuals[name][k], strict=True):
                writer.writerow([name, view, *(repr(float(x)) for x in (u, v, du, dv))])
    return buf.getvalue()


def write_report(folder, res: BundleResult, depth_mm: float = 700.0) -> list[Path]:
    """residuals.csv (:func:`residuals_csv`), residuals.png and vertical_disagreement.png in ``folder``
    (which must exist; ``psvs calibrate --report`` creates it). Both figures plot the image in pixels with
    equal axes (one px as long across as down), so each has the image's shape; the twin map is
    :func:`vertical_disagreement` at ``depth_mm`` on a 16 px grid."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = Path(folder)
    rig = res.rig
    w, h = rig.camera.image_size_px
    fig, ax = plt.subplots(figsize=(8, 6.2))
    scale = 200.0
    for view, colour in (("left", "tab:red"), ("right", "tab:blue")):
        pts = np.concatenate([res.observed[n][0 if view == "left" else 1] for n in res.observed])
        r = np.concatenate([res.residuals[n][0 if view == "left" else 1] for n in res.residuals])
        ax.quiver(pts[:, 0], pts[:, 1], r[:, 0] * scale, r[:, 1] * scale, color=colour, angles="xy",
                  scale_units="xy", scale=1, width=0.002, label=f"{view} view (RMS {res.rms_by_view[view]:.3f} px)")
    ax.set_xlim(0, w - 1)
    ax.set_ylim(h - 1, 0)
    ax.set_aspect("equal")
    ax.set_xlabel("u (px)")
    ax.set_ylabel("v (px)")
    ax.set_title(f"Reprojection residuals x{scale:.0f} (RMS {res.rms_px:.3f} px)")
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    out = [folder / "residuals.csv", folder / "residuals.png", folder / "vertical_disagreement.png"]
    write_atomic(out[0], residuals_csv(res))
    _save(fig, out[1])

    step = 16
    u, v, dv = vertical_disagreement(rig, depth_mm, step_px=step)
    fig, ax = plt.subplots(figsize=(8, 6.2))
    lim = max(float(np.nanmax(np.abs(dv))), 0.5) if np.isfinite(dv).any() else 1.0
    # each grid value fills its step x step cell of pixels; the axes span the image's pixels, one unit a
    # pixel both ways, so the map has the image's shape (a 1440 x 1080 image is 4:3, not square)
    half = step / 2
    im = ax.imshow(dv, extent=(u.min() - half, u.max() + half, v.max() + half, v.min() - half), cmap="coolwarm",
                   vmin=-lim, vmax=lim, aspect="equal", interpolation="nearest")
    if np.isfinite(dv).sum() > 4 and np.nanmax(dv) - np.nanmin(dv) > 1e-3:
        cs = ax.contour(u, v, dv, colors="k", linewidths=0.6)
        ax.clabel(cs, fontsize=7, fmt="%.1f")
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.set_aspect("equal")
    fig.colorbar(im, ax=ax, label="v_right - v_left (px)")
    ax.set_xlabel("u, left view (px)")
    ax.set_ylabel("v, left view (px)")
    ax.set_title(f"Where the twin of a left-view pixel lies, rows off, at Z = {depth_mm:.0f} mm")
    fig.tight_layout()
    _save(fig, out[2])
    return out


def _save(fig, path: Path) -> None:
    import matplotlib.pyplot as plt
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    write_atomic(path, buf.getvalue())
