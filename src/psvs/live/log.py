"""Per-frame track logs: CSV rows ``frame,tracked,seed_u,seed_v,n_pairs,disparity_px,depth_mm,latency_ms``."""
from __future__ import annotations

from psvs.io.atomic import write_atomic
from psvs.live.tracker import TrackStep

HEADER = "frame,tracked,seed_u,seed_v,n_pairs,disparity_px,depth_mm,latency_ms\n"


def log_row(step: TrackStep) -> str:
    """One CSV row (with newline); empty seed and NaN values when the edge was lost."""
    u, v = step.seed_px if step.seed_px is not None else ("", "")
    n = len(step.pair) if step.pair is not None else 0
    return (f"{step.frame},{int(step.ok)},{u},{v},{n},{step.disparity_px:.4f},{step.depth_mm:.4f},"
            f"{step.elapsed_s * 1e3:.3f}\n")


def write_log(path, steps: list[TrackStep]) -> None:
    write_atomic(path, HEADER + "".join(log_row(s) for s in steps))
