"""What a simulated seam-tracking run will cost, checked before any work (``psvs track`` and the web page's Robot
step), and the sensor window's default height."""
from __future__ import annotations

from psvs.optics.rig import Rig
from psvs.robot.controller import TrackConfig


def default_roi_rows(rig: Rig) -> int:
    """The sensor window's rows: those that span the same angle (length of seam) as 32 rows of the paper's camera
    (32 on it, 66 on mv1440), at least 8, at most the camera's rows."""
    from psvs.optics.scale import pixel_scale
    return min(int(rig.camera.image_size_px[1]), max(8, round(32 * pixel_scale(rig.camera))))


def check_session_work(rig: Rig, hint: str) -> float:
    """The hand-eye session's renders within the time and memory limits (ValueError naming them and ``hint``):
    their estimated wall time, s."""
    from psvs.robot.handeye_session import CELL_SUPERSAMPLE, CELL_VIEWS
    from psvs.simulate.render import check_render_work, render_seconds
    check_render_work(rig, CELL_SUPERSAMPLE, CELL_VIEWS, f"the hand-eye session's {CELL_VIEWS} views", hint)
    return render_seconds(rig, CELL_SUPERSAMPLE, CELL_VIEWS)


def track_work(rig: Rig, cfg: TrackConfig, seam_mm: float, length_mm: float | None,
               check_share: float | None) -> tuple[float, str, str]:
    """What welding ``length_mm`` (None: the whole ``seam_mm``) costs: (the estimated wall time of its control
    cycles and of the rolling self-check's whole frames at ``check_share`` of the sensor's time (None: no
    self-check), s; the cycles in words; the self-check's frames in words, '' without one), for
    :func:`psvs._budget.check_time` before any work."""
    from psvs.robot.cells import SimulationConfig
    from psvs.robot.loop import CYCLE_SECONDS, RUN_IN_OUT_MM, check_frames_expected, cycle_seconds, track_cycles
    from psvs.simulate.render import render_seconds
    length = seam_mm if length_mm is None else min(length_mm, seam_mm)
    cycles = track_cycles(length, cfg)
    w, k = rig.camera.image_size_px[0], SimulationConfig().supersample
    seconds, frames_text = cycles * cycle_seconds(rig, cfg), ""
    if check_share is not None:        # the self-check's whole frames, rendered when it asks for one
        frames = check_frames_expected(cycles, check_share)
        seconds += frames * render_seconds(rig, k, 1)
        frames_text = f"{frames} whole frames for the self-check"
    cycles_text = (f"{cycles} control cycles ({length:g} mm of seam and {RUN_IN_OUT_MM:g} mm to start and stop at "
                   f"{cfg.speed_mm_s:g} mm/s, {cfg.rate_hz:g} Hz), each a {w}x{cfg.roi_rows} px window x {k * k} "
                   f"samples and {CYCLE_SECONDS * 1e3:g} ms of sensing")
    return seconds, cycles_text, frames_text
