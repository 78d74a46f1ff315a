"""Seam tracking, one core: the seam sensor's stage of one control cycle (32-row window of the complex
image: both groove edges matched with their twins, sub-pixel, exact triangulation, groove-root fit) <= 10 ms.
The same on the misaligned build (a window taller by the twins' row offset, matching on the rectified
rows); on the machine-vision build (mv1440_misaligned: 1440 px wide, the 66 rows psvs track reads there)
<= 20 ms, half a cycle at 25 Hz. ``psvs track --handeye FILE`` starts tracking (the command in a fresh
process: imports, the file, the rig's tables, the first control cycle) in <= 2 s."""
from dataclasses import replace

import cv2

from psvs import default_rig
from psvs.robot.arm import Arm
from psvs.robot.cells import SimulationConfig
from psvs.robot.controller import UP, TrackConfig
from psvs.robot.handeye_session import true_cam2flange
from psvs.robot.loop import sensor_setup, teach
from psvs.robot.mounting import HOME_Q
from psvs.robot.seam import fit_seam_point
from psvs.robot.sensor import auto_seed
from psvs.robot.workpiece import seam_workpiece
from psvs.simulate.render import render
from psvs.simulate.sequence import scene_in_rig_frame
from psvs.transforms import concat, invert_transform, transform_points

cv2.setNumThreads(1)


def _sensor_stage(rig=None, roi_rows: int = 32):
    """The first frame of a run (the torch at the taught start, the true mounting), rendered once; timed:
    the sensor started on it, both edges measured, the groove root fitted in the base frame."""
    rig = rig or default_rig()
    cfg = TrackConfig(roi_rows=roi_rows)
    wp = seam_workpiece("weld_seam", cfg.camera_distance_mm)
    arm = Arm(HOME_Q)
    teach(wp, cfg, SimulationConfig(), arm)
    cam2base = concat(true_cam2flange(cfg), arm.fkine())
    setup, _ = sensor_setup(rig, cfg)
    img = render(scene_in_rig_frame(wp.scene, invert_transform(cam2base)), setup.rig, seed=1).image
    setup = replace(setup, seed_px=auto_seed(img))

    def run():
        obs = setup.start(img).measure(img)
        a, b = (transform_points(cam2base, e) for e in obs.edges_mm)
        fit_seam_point(a, b, cfg.groove_depth_mm, UP)
    return run


def _start_with_handeye():
    import subprocess
    import sys
    import tempfile
    import time
    from pathlib import Path

    from psvs.robot.handeye import calibrate_from_views
    from psvs.robot.handeye_io import save_handeye
    from psvs.robot.handeye_session import CELL_GRID, cell_views
    cfg = TrackConfig()
    images, flanges = cell_views(default_rig(), cfg, Arm(HOME_Q))
    tmp = Path(tempfile.mkdtemp())
    save_handeye(tmp / "handeye.toml", calibrate_from_views(images, flanges, default_rig(), CELL_GRID),
                 "simulated cell", "default")

    def run():
        """The command as a user types it, timed from its start to the line it prints after the first cycle."""
        cmd = [sys.executable, "-m", "psvs", "track", "weld_seam", "--rig", "default", "--handeye",
               str(tmp / "handeye.toml"), "--length", "1", "--no-bag", "-o", str(tmp / "run")]
        t0 = time.perf_counter()
        with subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True) as proc:
            for line in proc.stdout:
                if line.startswith("tracking: first control cycle"):
                    break
            else:
                raise RuntimeError(f"psvs track ended (status {proc.wait()}) before its first control cycle")
            elapsed = time.perf_counter() - t0
            proc.kill()
        return elapsed
    return run


RATIOS = [("mv1440_misaligned / misaligned, seam sensor stage (same run)",
           "seam sensor stage, mv1440_misaligned build (1440 px wide, 66 rows + the twins' offset)",
           "seam sensor stage, misaligned build (640x51 window, rectified rows)")]


def cases():
    from psvs.io.params import load_rig
    return [("seam sensor stage per control cycle (640x32 window, 2 edges)", _sensor_stage, 0.010),
            ("seam sensor stage, misaligned build (640x51 window, rectified rows)",
             lambda: _sensor_stage(load_rig("misaligned")), 0.010),
            ("seam sensor stage, mv1440_misaligned build (1440 px wide, 66 rows + the twins' offset)",
             lambda: _sensor_stage(load_rig("mv1440_misaligned"), 66), 0.020),
            ("psvs track --handeye: a fresh process to its first control cycle", _start_with_handeye, 2.0)]
