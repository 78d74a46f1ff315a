"""Robot path control with the PSVS on a PUMA-family arm: arm, hand-eye, seam sensor, path model, loop."""
import lazy_loader as _lazy

# The package's public face: what other packages and users may import from it. Each name is loaded on
# first use (scikit-image's lazy_loader), so importing the package loads none of its modules.
__getattr__, __dir__, __all__ = _lazy.attach(
    __name__,
    submodules=[],
    submod_attrs={
        "arm": ["Arm"],
        "bag": ["write_bag"],
        "budget": ["check_session_work", "default_roi_rows", "track_work"],
        "cells": ["SimulationConfig"],
        "controller": ["TrackConfig"],
        "drift": ["DRIFT_STOP", "DriftWatch", "HealthNote"],
        "handeye": ["calibrate_from_views", "check_mount_pinned", "check_robot_accuracy"],
        "handeye_io": ["check_same_rig", "load_handeye", "read_views", "save_handeye", "write_views"],
        "handeye_session": ["CELL_GRID", "CELL_SUPERSAMPLE", "CELL_VIEWS", "cell_views", "nominal_cam2flange",
                            "true_cam2flange"],
        "loop": ["CYCLE_SECONDS", "RUN_IN_OUT_MM", "SHARE", "Watching", "check_frames_expected", "cycle_seconds",
                 "drift_watch", "sensor_range", "track", "track_cycles"],
        "mounting": ["HOME_Q", "tool2flange"],
        "recording": ["RunRecorder", "publish_stop", "replay_recording"],
        "report": ["write_report"],
        "run_log": ["HEALTH_LOG_COLUMNS", "LOG_COLUMNS", "RunLog", "read_log_csv"],
        "view3d": ["cam2base", "sensor_view"],
        "workpiece": ["seam_workpiece"],
    },
)
