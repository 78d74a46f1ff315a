"""Per-frame logs of ``psvs live``: CSV rows ``frame,tracked,seed_u,seed_v,n_pairs,disparity_px,depth_mm,
latency_ms`` for the tracked edge, and with ``--dense`` the columns ``dense_median_z_mm,dense_answered_pct,
dense_ms`` (the edge's columns empty when no edge is tracked)."""
from __future__ import annotations

from psvs.io.atomic import write_atomic
from psvs.live.dense import DenseFrame
from psvs.live.tracker import TrackStep

HEADER = "frame,tracked,seed_u,seed_v,n_pairs,disparity_px,depth_mm,latency_ms\n"
DENSE_COLUMNS = "dense_median_z_mm,dense_answered_pct,dense_ms"


def log_row(step: TrackStep) -> str:
    """One CSV row (with newline); empty seed and NaN values when the edge was lost."""
    u, v = step.seed_px if step.seed_px is not None else ("", "")
    n = len(step.pair) if step.pair is not None else 0
    return (f"{step.frame},{int(step.ok)},{u},{v},{n},{step.disparity_px:.4f},{step.depth_mm:.4f},"
            f"{step.elapsed_s * 1e3:.3f}\n")


def write_log(path, steps: list[TrackStep | None], dense: list[DenseFrame] | None = None) -> None:
    """The log of ``steps`` (None: no edge tracked), with the dense columns when ``dense`` (one per step)."""
    if dense is None:
        write_atomic(path, HEADER + "".join(log_row(s) for s in steps))
        return
    rows = []
    for k, (s, d) in enumerate(zip(steps, dense)):
        edge = log_row(s)[:-1] if s is not None else f"{k},,,,,,,"
        rows.append(f"{edge},{d.median_z_mm:.4f},{d.answered_pct:.3f},{d.elapsed_s * 1e3:.3f}\n")
    write_atomic(path, HEADER[:-1] + "," + DENSE_COLUMNS + "\n" + "".join(rows))
