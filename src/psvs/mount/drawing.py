"""The mount's dimensioned drawing: a top view (X across, Z up the page) and a side view (Z across, Y
down the page, as the camera sees it), with each mirror's centre, angle and glass size as text.

Every dimension is one text element (the SVG keeps text as text, ``svg.fonttype = none``), so the numbers
can be read back from the file: ``M1 centre x=2.66 y=0.00 z=24.66 mm``, ``M1 angle 45.00 deg``, ``M1 glass
21.26 x 50.01 x 3.00 mm`` and ``overall ... mm``.
"""
from __future__ import annotations

import io
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from psvs.mount.layout import Box, MountLayout, Slab  # noqa: E402
from psvs.optics.mirrors import mirror_planes  # noqa: E402
from psvs.optics.rig import MIRROR_NAMES  # noqa: E402


def mirror_angle_deg(plane) -> float:
    """The mirror's angle in the top view: its in-plane axis s from the optical axis +Z toward +X, deg."""
    return math.degrees(math.atan2(plane.s_axis[0], plane.s_axis[2]))


def dimension_lines(layout: MountLayout, overall_mm: tuple[float, float, float]) -> list[str]:
    """The drawing's dimension texts, one per line (what :func:`render_drawing` writes)."""
    planes = mirror_planes(layout.rig)
    m = layout.rig.mirrors
    lines = []
    for name in MIRROR_NAMES:
        p, e = planes[name], layout.glass[name]
        (s0, s1), (t0, t1) = e.along_mm, e.height_mm
        c = p.point + 0.5 * (s0 + s1) * p.s_axis + np.array([0.0, 0.5 * (t0 + t1), 0.0])
        thick = m.plate_thickness_mm if name == "m1" else layout.seats[name].back_offset_mm
        lines += [f"{name.upper()} centre x={c[0]:.2f} y={c[1]:.2f} z={c[2]:.2f} mm",
                  f"{name.upper()} angle {mirror_angle_deg(p):.2f} deg",
                  f"{name.upper()} glass {s1 - s0:.2f} x {t1 - t0:.2f} x {thick:.2f} mm"]
    lines.append("overall {:.1f} x {:.1f} x {:.1f} mm (X x Y x Z)".format(*overall_mm))
    lines.append(f"floor top y={layout.floor_y_mm:.2f} mm, lid underside y={-layout.floor_y_mm:.2f} mm")
    return lines


def _outline(ax, part, axes: tuple[int, int], **kw) -> None:
    if isinstance(part, Box):
        c = part.corners()[:, list(axes)]
        from scipy.spatial import ConvexHull
        try:
            h = c[ConvexHull(c).vertices]
        except Exception:      # a box seen edge-on is a line
            h = c[[0, -1]]
        ax.fill(h[:, 0], h[:, 1], **kw)
    elif isinstance(part, Slab) and axes == (0, 2):
        p = np.asarray(part.outline_xz)
        ax.fill(p[:, 0], p[:, 1], fill=False, **{k: v for k, v in kw.items() if k != "alpha"})


def render_drawing(layout: MountLayout, segments: list, overall_mm: tuple) -> tuple[bytes, bytes]:
    """The drawing as (SVG bytes, PNG bytes): top and side views with the mirrors, the carriers, a few of
    the field rays, and the dimension texts of :func:`dimension_lines`."""
    with plt.rc_context({"svg.fonttype": "none", "font.size": 7}):
        fig, (top, side, text) = plt.subplots(1, 3, figsize=(16, 6.5), gridspec_kw={"width_ratios": [3, 2, 2.2]})
        planes = mirror_planes(layout.rig)
        for (p0, p1) in segments:
            k = np.linspace(0, len(p0) - 1, 24).astype(int)
            far = np.minimum(1.0, 150.0 / np.maximum(np.linalg.norm(p1[k] - p0[k], axis=1), 1e-9))
            q1 = p0[k] + far[:, None] * (p1[k] - p0[k])
            for a, b in zip(p0[k], q1, strict=True):
                top.plot([a[0], b[0]], [a[2], b[2]], color="gold", lw=0.3)
                side.plot([a[2], b[2]], [a[1], b[1]], color="gold", lw=0.3)
        for part in layout.solids:
            _outline(top, part, (0, 2), color="0.6", alpha=0.5, lw=0.5)
            _outline(side, part, (2, 1), color="0.6", alpha=0.3, lw=0.5)
        for name in MIRROR_NAMES:
            p, e = planes[name], layout.glass[name]
            ends = np.array([p.point + s * p.s_axis for s in e.along_mm])
            top.plot(ends[:, 0], ends[:, 2], color="tab:blue", lw=2)
            mid = ends.mean(0)
            top.annotate(f"{name.upper()} {mirror_angle_deg(p):.1f}°", (mid[0], mid[2]), fontsize=7,
                         xytext=(4, 4), textcoords="offset points")
            zs = ends[:, 2]
            side.fill_between([zs.min(), zs.max()], e.height_mm[0], e.height_mm[1], color="tab:blue", alpha=0.3)
            side.text(zs.mean(), e.height_mm[0] - 2, name.upper(), ha="center", fontsize=7)
        top.plot([0], [0], "k^")
        top.set(title="top view (camera at O, light upward)", xlabel="X mm", ylabel="Z mm", aspect="equal")
        side.set(title="side view", xlabel="Z mm", ylabel="Y mm (down)", aspect="equal")
        side.invert_yaxis()
        text.axis("off")
        for i, line in enumerate(dimension_lines(layout, overall_mm)):
            text.text(0.0, 1.0 - i * 0.045, line, transform=text.transAxes, fontsize=7, family="monospace",
                      va="top")
        fig.tight_layout()
        out = []
        for fmt in ("svg", "png"):
            buf = io.BytesIO()
            fig.savefig(buf, format=fmt, dpi=150, metadata={"Date": None} if fmt == "svg" else None)
            out.append(buf.getvalue())
        plt.close(fig)
    return out[0], out[1]
