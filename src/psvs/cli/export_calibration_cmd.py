"""``psvs export-calibration``: each view of a rig as a ROS CameraInfo YAML and both as an OpenCV
FileStorage YAML (K, D, R, P of the rectified views; psvs.io.camera_info)."""
from __future__ import annotations

from pathlib import Path

from psvs.cli.common import add_range_arguments, measuring_rig, range_from_args
from psvs.io.atomic import check_output_folder
from psvs.io.camera_info import write_calibration_files
from psvs.optics.pinhole_views import pinhole_views


def add_parser(sub) -> None:
    p = sub.add_parser("export-calibration",
                       help="write a rig's views as ROS CameraInfo YAML (left.yaml, right.yaml) and an OpenCV "
                            "FileStorage (stereo.yml)",
                       description="Each view of the rig as a rectified stereo camera (K, D, R, P of the dual "
                                   "rectification over the working range): left.yaml and right.yaml in ROS "
                                   "camera_calibration_parsers' format (Tx in metres), stereo.yml for "
                                   "cv2.FileStorage (K1..P2, R, T, Q, mm). The right view is a pinhole exactly; "
                                   "the left is not (the M1 plate): the files state its model error in px. "
                                   "See docs/ros.md.")
    p.add_argument("rig", metavar="RIG.toml", help="a rig file, or a shipped rig's name (psvs rig list)")
    p.add_argument("-o", "--output", metavar="DIR", default="calibration",
                   help="folder for the three files (created; default: ./calibration)")
    add_range_arguments(p)
    p.set_defaults(run=run)


def run(args) -> int:
    out = check_output_folder(args.output)
    rig = measuring_rig(args.rig)
    near_mm, far_mm = range_from_args(args, rig)               # in front of the rig's mirrors, as every command
    views = pinhole_views(rig, near_mm, far_mm)
    for path in write_calibration_files(out, views, near_mm, far_mm, Path(args.rig).stem):
        print(f"wrote {path}")
    for name, view in views.items():
        du, dv = view.error_px
        print(f"{name}: model error over the image {du:.3g} px in columns, {dv:.3g} px in rows")
    return 0
