"""The rig as built: where a misaligned build's mirrors and virtual cameras are, and where twins land.

Left: top view (XZ plane, mm) of the designed mirrors (grey) and of examples/rigs/misaligned.toml's
mirrors with their errors magnified 20x (colour), the real camera O and both virtual centres (the build's
displacement magnified 20x too). Right: rows off (px) between a left-view pixel and its twin at 700 mm
on that build. Writes docs/img/build_model.png, or the path given as the first argument:
``.venv/bin/python examples/plot_build.py [OUT.png]``.
"""
# %%
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from psvs.calibrate.report import vertical_disagreement  # noqa: E402
from psvs.io.params import load_rig  # noqa: E402
from psvs.optics.mirrors import mirror_planes, virtual_centre  # noqa: E402
from psvs.optics.rig import MIRROR_NAMES, MirrorError  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
build = load_rig(ROOT / "examples" / "rigs" / "misaligned.toml")
design = build.with_errors({n: MirrorError() for n in MIRROR_NAMES}).replace(box_rotation_rad=(0.0, 0.0, 0.0))
GAIN = 20.0
shown = design.with_errors({n: MirrorError(tuple(GAIN * t for t in build.mirrors.error(n).tilt_rad),
                                           GAIN * build.mirrors.error(n).shift_mm) for n in MIRROR_NAMES}
                           ).replace(box_rotation_rad=tuple(GAIN * r for r in build.mirrors.box_rotation_rad))

# %%
fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 5.2))
for rig, style, label in ((design, dict(color="0.6", lw=3), "design"), (shown, dict(lw=1.2), "build (errors x20)")):
    for k, (name, plane) in enumerate(mirror_planes(rig).items()):
        if name == "m1_back":
            continue
        ends = plane.point + np.outer([-25.0, 25.0], plane.s_axis)
        ax.plot(ends[:, 0], ends[:, 2], **style, label=label if k == 0 else None)
        if rig is design:
            ax.annotate(name.upper(), plane.point[[0, 2]] + [4, -6], fontsize=9)
for view, colour in (("left", "tab:red"), ("right", "tab:blue")):
    c0, c1 = virtual_centre(design, view), virtual_centre(build, view)
    shown_c = c0 + GAIN * (c1 - c0)
    ax.plot(*c0[[0, 2]], "o", color="0.5")
    ax.plot(*shown_c[[0, 2]], "o", color=colour, label=f"O{1 if view == 'left' else 2}, build (x20)")
ax.plot(0, 0, "ks", label="camera O")
ax.set_xlabel("X (mm)")
ax.set_ylabel("Z (mm)")
ax.set_aspect("equal")
ax.legend(fontsize=8, loc="upper right")
ax.set_title("Top view: the mirrors as designed and as built")
u, v, dv = vertical_disagreement(build, 700.0, step_px=8)
im = bx.imshow(dv, extent=(u.min(), u.max(), v.max(), v.min()), cmap="coolwarm")
fig.colorbar(im, ax=bx, label="v_right - v_left (px)")
bx.set_xlabel("u, left view (px)")
bx.set_ylabel("v, left view (px)")
bx.set_title("Twin rows off (px), Z = 700 mm")
fig.tight_layout()
out = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "docs" / "img" / "build_model.png"
fig.savefig(out, dpi=90)
print(f"wrote {out}")
