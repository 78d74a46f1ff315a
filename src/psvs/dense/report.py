"""Files of a dense-disparity evaluation: scores (JSON, Markdown) and pictures (PNG)."""
from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np

from psvs.dense.evaluate import Evaluation
from psvs.io.atomic import write_atomic


def scores_markdown(ev: Evaluation, title: str) -> str:
    """A Markdown table of every method's scores and time, and the separated views' PSNR."""
    lines = [f"### {title}", "", "| method | bad-1 % | bad-2 % | MAE px | answered % | time s |",
             "|---|---:|---:|---:|---:|---:|"]
    for name, s in ev.scores.items():
        lines.append(f"| {name} | {s['bad1_pct']:.1f} | {s['bad2_pct']:.1f} | {s['mae_px']:.2f} | "
                     f"{s['coverage_pct']:.1f} | {ev.seconds.get(name, float('nan')):.2f} |")
    lines += ["", f"Separated views (from the default mode's disparity): PSNR left {ev.psnr_left_db:.1f} dB, "
                  f"right {ev.psnr_right_db:.1f} dB; separation {ev.seconds['view separation']:.1f} s.", ""]
    return "\n".join(lines)


def figure_png(ev: Evaluation, d_max: float) -> bytes:
    """Complex image, our disparity, ground truth, and the two separated views, side by side (PNG bytes)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 3, figsize=(15, 7.2))
    panels = [(ev.complex_image, "complex image 0.5 L + 0.5 R", "gray", 0, 255),
              (ev.disparity, "psvs dense: left-view disparity", "magma", 0, d_max),
              (ev.truth, "ground truth", "magma", 0, d_max),
              (ev.left_view, f"separated left view ({ev.psnr_left_db:.1f} dB)", "gray", 0, 255),
              (ev.right_view, f"separated right view ({ev.psnr_right_db:.1f} dB)", "gray", 0, 255),
              (np.where(np.isfinite(ev.truth), ~(np.abs(ev.disparity - ev.truth) <= 2), 0.5),
               "bad-2 pixels (white; grey: no truth)", "gray", 0, 1)]
    for ax, (img, title, cmap, lo, hi) in zip(axes.ravel(), panels, strict=False):
        # nearest: a smoothing resampler would spread the truth's NaN edges over whole areas
        ax.imshow(img, cmap=cmap, vmin=lo, vmax=hi, interpolation="nearest")
        ax.set_title(title, fontsize=10)
        ax.axis("off")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=56)
    plt.close(fig)
    return buf.getvalue()


def write_report(folder, ev: Evaluation, title: str, d_max: float) -> list[Path]:
    """scores.json, report.md and figure.png in ``folder`` (which must exist), each written atomically."""
    folder = Path(folder)
    data = {"title": title, "scores": ev.scores, "seconds": ev.seconds,
            "psnr_db": {"left": ev.psnr_left_db, "right": ev.psnr_right_db}}
    paths = [folder / "scores.json", folder / "report.md", folder / "figure.png"]
    write_atomic(paths[0], json.dumps(data, indent=2) + "\n")
    write_atomic(paths[1], scores_markdown(ev, title))
    write_atomic(paths[2], figure_png(ev, d_max))
    return paths
