"""``psvs handeye``: where the PSVS sits on the flange, from circle-grid views with their flange poses (a
views folder, or rendered in the simulated cell), written as handeye.toml for ``psvs track --handeye``."""
from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

import numpy as np

from psvs._budget import check_memory
from psvs.cli.common import add_rig_argument, check_distinct, check_output_path, measuring_rig
from psvs.io.atomic import check_output_folder


def add_parser(sub) -> None:
    p = sub.add_parser("handeye", help="calibrate where the PSVS sits on the robot's flange (hand-eye)",
                       description="Hand-eye calibration (AX = XB, Park & Martin) from complex images of a circle "
                                   "grid taken at known flange poses: VIEWS_DIR holds view_NN.png, target.toml "
                                   "and flange_poses.csv (image,x_mm,y_mm,z_mm,qx,qy,qz,qw, base frame). "
                                   "Without VIEWS_DIR the views are rendered in the simulated PUMA cell of "
                                   "psvs track. Writes the transform, its residuals and the method to "
                                   "HANDEYE.toml. See docs/robot.md.")
    p.add_argument("views", nargs="?", metavar="VIEWS_DIR", help="a hand-eye views folder (default: the "
                                                                  "simulated cell)")
    add_rig_argument(p)
    p.add_argument("--true-rig", metavar="RIG", help="simulated cell only: the rig as built, through which the "
                                                     "views are rendered (default: --rig)")
    p.add_argument("--views-count", type=int, default=12, metavar="N",
                   help="simulated cell only: how many views (default 12)")
    p.add_argument("--save-views", metavar="DIR", help="simulated cell only: also write the views as a folder")
    p.add_argument("--robot-accuracy-mm", type=float, default=0.5, metavar="MM",
                   help="the robot's stated flange pose accuracy (default 0.5 mm): the fit is refused when its "
                        "residual is beyond what this and the detector's precision explain (docs/right-or-refuse.md)")
    p.add_argument("-o", "--output", metavar="HANDEYE.toml", required=True, help="the hand-eye file to write")
    p.set_defaults(run=run)


def _check_cell_work(views: int, rig, supersample: int) -> None:
    """--views-count: at least 3, and its renders (and the images, all held until the calibration) within
    the time and memory limits, before any is rendered."""
    from psvs.simulate.render import check_render_work
    if views < 3:
        raise ValueError(f"--views-count must be at least 3 (the hand-eye session needs them), got {views}")
    check_render_work(rig, supersample, views, f"--views-count {views}", "fewer --views-count")
    w, h = rig.camera.image_size_px
    check_memory(views * w * h, f"--views-count {views} ({views} images of {w}x{h} px held at once)",
                 "fewer --views-count")


def run(args) -> int:
    from psvs.io.params import load_rig, rig_digest
    from psvs.robot.arm import Arm
    from psvs.robot.controller import TrackConfig
    from psvs.robot.handeye import calibrate_from_views, check_robot_accuracy
    from psvs.robot.handeye_io import read_views, save_handeye, write_views
    from psvs.robot.handeye_session import CELL_GRID, CELL_SUPERSAMPLE, cell_views, true_cam2flange
    from psvs.robot.mounting import HOME_Q

    out = check_output_path(args.output, (".toml",))
    if args.views is not None and (args.true_rig or args.save_views):
        raise ValueError("--true-rig and --save-views are for the simulated cell, not a views folder")
    save = check_output_folder(args.save_views, "--save-views folder") if args.save_views else None
    check_distinct({"-o": args.output, "--save-views": args.save_views},
                   {"VIEWS_DIR": args.views, "--rig": args.rig, "--true-rig": args.true_rig})
    check_robot_accuracy(args.robot_accuracy_mm, "--robot-accuracy-mm")
    rig = measuring_rig(args.rig)
    truth = None
    if args.views is not None:
        images, flanges, grid = read_views(args.views, expect_size=rig.camera.image_size_px)
        source = str(Path(args.views))
    else:
        true_rig = load_rig(args.true_rig) if args.true_rig else None
        _check_cell_work(args.views_count, true_rig or rig, CELL_SUPERSAMPLE)
        cfg = TrackConfig()
        images, flanges = cell_views(true_rig or rig, cfg, Arm(HOME_Q), args.views_count)
        grid, source, truth = CELL_GRID, "simulated cell", true_cam2flange(cfg)
    he = calibrate_from_views(images, flanges, rig, grid, robot_accuracy_mm=args.robot_accuracy_mm)
    if save is not None:
        write_views(save, images, flanges, grid)
    he = dataclasses.replace(he, rig_sha256=rig_digest(rig))
    save_handeye(out, he, source, Path(args.rig).stem if args.rig else "default")
    for k, why in he.skipped:
        print(f"skipped view {k}: {why}", file=sys.stderr)
    print(f"{len(images) - len(he.skipped)} of {len(images)} views used; target fit RMS per view (mm): "
          + ", ".join(f"{r:.3f}" for r in he.target_rms_mm))
    print(f"consistency: the target's pose over the views spreads {he.spread_mm:.3f} mm, "
          f"{math.degrees(he.spread_rad):.3f} deg")
    print(f"reprojection RMS of the discs in both views: {he.reprojection_rms_px:.3f} px")
    t = he.cam2flange[:3, 3]
    print(f"PSVS on the flange: ({t[0]:.2f}, {t[1]:.2f}, {t[2]:.2f}) mm, 1-sigma {he.mount_sigma_mm:.2f} mm on "
          f"each axis and {math.degrees(he.mount_sigma_rad):.3f} deg from the detector's precision and the robot's "
          "stated accuracy")
    if truth is not None:
        err = np.linalg.norm(he.cam2flange[:3, 3] - truth[:3, 3])
        ang = math.degrees(np.arccos(np.clip((np.trace(truth[:3, :3].T @ he.cam2flange[:3, :3]) - 1) / 2, -1, 1)))
        print(f"against the simulated hardware's true mounting: {err:.3f} mm, {ang:.4f} deg")
    print(f"wrote {out}" + (f" and the views to {save}" if save else ""))
    return 0
