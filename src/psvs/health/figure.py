"""The check's map: where in the field the twins stand off their rows (``psvs check --map OUT.png``)."""
from __future__ import annotations

import io

import numpy as np

from psvs.health.check import HealthCheck
from psvs.health.field import field_basis


def offset_figure(check: HealthCheck) -> bytes:
    """A PNG (bytes) of the fitted row-offset field over the left view's rectified grid, each judged tile's
    measured offset as a dot in the same colours, and the verdict and figures in the title. Drawn on its own
    Figure (no pyplot state: safe from the web server's worker threads)."""
    from matplotlib.figure import Figure
    h, w = check.grid_shape
    fig = Figure(figsize=(8, 6.4))
    ax = fig.subplots()
    finite = np.isfinite(check.coefficients).all()
    lim = max(float(np.nanmax(np.abs(check.offset_px))) if len(check.offset_px) else 0.0, check.tolerance_px)
    if finite:
        step = max(4, min(h, w) // 60)
        vv, uu = np.mgrid[0:h:step, 0:w:step]
        fieldmap = (field_basis(np.column_stack([uu.ravel(), vv.ravel()]).astype(float), (h, w))
                    @ check.coefficients).reshape(uu.shape)
        lo, hi = check.centre_px.min(axis=0) - step, check.centre_px.max(axis=0) + step
        outside = (uu < lo[0]) | (uu > hi[0]) | (vv < lo[1]) | (vv > hi[1])
        fieldmap = np.where(outside, np.nan, fieldmap)          # the field where tiles were judged, not beyond
        im = ax.imshow(fieldmap, extent=(-0.5, w - 0.5, h - 0.5, -0.5), cmap="coolwarm", vmin=-lim, vmax=lim,
                       aspect="equal", interpolation="bilinear")
        fig.colorbar(im, ax=ax, label="row offset of the twin, right - left (px)")
    if len(check.centre_px):
        ax.scatter(check.centre_px[:, 0], check.centre_px[:, 1], c=check.offset_px, cmap="coolwarm", vmin=-lim,
                   vmax=lim, edgecolors="k", linewidths=0.4, s=18)
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.set_xlabel("u', left view's rectified grid (px)")
    ax.set_ylabel("v' (px)")
    figures = ("" if not finite else f": RMS {check.row_offset_rms_px:.2f} +- {check.uncertainty_px:.2f} px, "
               f"largest {check.row_offset_max_px:.2f} px")
    ax.set_title(f"{check.verdict}{figures} ({check.tiles} tiles, tolerance {check.tolerance_px:g} px)", fontsize=10)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    return buf.getvalue()
