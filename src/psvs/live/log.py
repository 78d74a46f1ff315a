"""Per-frame logs of ``psvs live``: CSV rows ``frame,tracked,seed_u,seed_v,n_pairs,disparity_px,depth_mm,
latency_ms`` for the tracked edge, with ``--dense`` the columns ``dense_median_z_mm,dense_answered_pct,
dense_ms`` (the edge's columns empty when no edge is tracked), and last the frame's source columns
``camera_frame,timestamp_s,clock,dropped``: the camera's own frame counter, its timestamp (s) on ``clock``
(camera, host or file: psvs.live.camera.CLOCKS) and the frames lost just before it; with the rolling self-check
the columns ``health,row_offset_rms_px,row_offset_unc_px,health_tiles``: its latest verdict as of the frame
(psvs.health.rolling; empty before its first), the field's RMS and uncertainty (px) and the tiles judged."""
from __future__ import annotations

from psvs.io.atomic import write_atomic
from psvs.live.camera import Frame
from psvs.live.dense import DenseFrame
from psvs.live.tracker import TrackStep

HEADER = "frame,tracked,seed_u,seed_v,n_pairs,disparity_px,depth_mm,latency_ms\n"
DENSE_COLUMNS = "dense_median_z_mm,dense_answered_pct,dense_ms"
SOURCE_COLUMNS = "camera_frame,timestamp_s,clock,dropped"
HEALTH_COLUMNS = "health,row_offset_rms_px,row_offset_unc_px,health_tiles"


def log_row(step: TrackStep) -> str:
    """One CSV row (with newline); empty seed and NaN values when the edge was lost."""
    u, v = step.seed_px if step.seed_px is not None else ("", "")
    n = len(step.pair) if step.pair is not None else 0
    return (f"{step.frame},{int(step.ok)},{u},{v},{n},{step.disparity_px:.4f},{step.depth_mm:.4f},"
            f"{step.elapsed_s * 1e3:.3f}\n")


def source_cells(f: Frame) -> str:
    """A frame's source columns (no newline): counter, timestamp s (9 decimals: ns), clock, dropped."""
    return f"{f.counter},{f.timestamp_s:.9f},{f.clock},{f.dropped}"


def health_cells(check) -> str:
    """A frame's health columns (no newline): empty when the rolling check has not judged yet."""
    if check is None:
        return ",,,"
    return f"{check.verdict},{check.row_offset_rms_px:.4f},{check.uncertainty_px:.4f},{check.tiles}"


def write_log(path, steps: list[TrackStep | None], dense: list[DenseFrame] | None = None,
              frames: list[Frame] | None = None, health: list | None = None) -> None:
    """The log of ``steps`` (None: no edge tracked), with the dense columns when ``dense`` (one per step),
    the source columns when ``frames`` (the grabbed frames' metadata, one per step) and the health columns
    when ``health`` (the rolling check's latest HealthCheck or None, one per step)."""
    header = HEADER[:-1] + ("," + DENSE_COLUMNS if dense is not None else "") + \
        ("," + SOURCE_COLUMNS if frames is not None else "") + ("," + HEALTH_COLUMNS if health is not None else "") \
        + "\n"
    rows = []
    for k, s in enumerate(steps):
        row = log_row(s)[:-1] if s is not None else f"{k},,,,,,,"
        if dense is not None:
            d = dense[k]
            row += f",{d.median_z_mm:.4f},{d.answered_pct:.3f},{d.elapsed_s * 1e3:.3f}"
        if frames is not None:
            row += "," + source_cells(frames[k])
        if health is not None:
            row += "," + health_cells(health[k])
        rows.append(row + "\n")
    write_atomic(path, header + "".join(rows))
