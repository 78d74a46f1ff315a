"""Dual rectification of a build: epipolar curves in the complex image, rows in the rectified views.

For a grid of left-view pixels of examples/rigs/misaligned.toml, the right-view twins of the points their
rays see from 400 to 1200 mm (the epipolar curves, exact optics). Left: in the complex image, where the
curves leave the left pixel's row (dashed) by several rows. Right: the same twins in the right view's
rectified coordinates, each left pixel at its left-view rectified place: every curve lies on its left
pixel's row (the largest departure is printed). Writes docs/img/rectification.png, or the path given as the
first argument: ``.venv/bin/python examples/plot_rectification.py [OUT.png]``.
"""
# %%
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from psvs.io.params import load_rig  # noqa: E402
from psvs.optics.project import project_points  # noqa: E402
from psvs.optics.rectify import rectify  # noqa: E402
from psvs.optics.trace import trace_pixels  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
rig = load_rig(ROOT / "examples" / "rigs" / "misaligned.toml")
rect = rectify(rig, 400.0, 1200.0)
w, h = rig.camera.image_size_px

# %% epipolar curves of a grid of left pixels (exact: the left ray's points projected into the right view)
uu, vv = np.meshgrid(np.linspace(380, 620, 4), np.linspace(30, 450, 5))
left = np.column_stack([uu.ravel(), vv.ravel()])
rays = trace_pixels(left, rig, "left")
depths = np.linspace(400.0, 1200.0, 41)
fig, axes = plt.subplots(1, 2, figsize=(11, 4.4), layout="constrained")
worst = 0.0
for k, (o, d) in enumerate(zip(rays.origins_mm, rays.dirs, strict=True)):
    pts = o + ((depths - o[2]) / d[2])[:, None] * d
    uv, ok = project_points(pts, rig, "right")
    ok &= (uv[:, 0] >= 0) & (uv[:, 0] <= w - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= h - 1)
    if ok.sum() < 2:
        continue
    colour = plt.cm.viridis(k / len(left))
    axes[0].plot(uv[ok, 0], uv[ok, 1], color=colour, lw=1.5)
    axes[0].plot(*left[k], "o", color=colour, ms=4)
    axes[0].axhline(left[k, 1], color=colour, lw=0.6, ls="--")
    lr = rect.to_rectified(left[k:k + 1], "left")[0]
    rr = rect.to_rectified(uv[ok], "right")
    worst = max(worst, float(np.abs(rr[:, 1] - lr[1]).max()))
    axes[1].plot(rr[:, 0], rr[:, 1], color=colour, lw=1.5)
    axes[1].plot(*lr, "o", color=colour, ms=4)
    axes[1].axhline(lr[1], color=colour, lw=0.6, ls="--")
axes[0].set(xlim=(0, w - 1), ylim=(h - 1, 0), xlabel="u (px)", ylabel="v (px)",
            title="complex image: twins leave the left pixel's row")
rw, rh = rect.size_px
axes[1].set(xlim=(0, rw - 1), ylim=(rh - 1, 0), xlabel="u' (px)", ylabel="v' (px)",
            title=f"rectified views: on the row (largest departure {worst:.3f} px)")
fig.suptitle("misaligned.toml: epipolar curves of left pixels (dots), 400-1200 mm")
out = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "docs" / "img" / "rectification.png"
fig.savefig(out, dpi=110)
print(f"wrote {out}: largest row departure after rectification {worst:.3f} px")
