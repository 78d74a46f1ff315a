"""``psvs disparity``: dense disparity (and separated views, depth, point cloud) of one complex image."""
from __future__ import annotations

import sys
import warnings

import numpy as np

from psvs.cli.common import check_output_path, check_working_range
from psvs.dense import dense_disparity, separate_views, write_cloud_ply
from psvs.dense.build import RigDense, dense_on_rig, rig_cloud
from psvs.dense.disparity import check_dense_memory, check_range
from psvs.dense.params import DEFAULT, FAST
from psvs.imaging.grey import to_grey8
from psvs.io.atomic import output_batch
from psvs.io.images import read_grey, write_npy, write_png
from psvs.io.params import load_rig
from psvs.measure.triangulate import MODELS
from psvs.optics.search_range import disparity_range, rectification_for


def add_parser(sub) -> None:
    p = sub.add_parser("disparity", help="dense disparity and view separation of a complex image",
                       description="Dense left-view disparity (u_l - u_r, px) of a complex image by its echoes "
                                   "(docs/dense.md). Writes a float32 HxW .npy, NaN where there is no answer; "
                                   "optionally the separated left and right views, the depth map and a point "
                                   "cloud through the rig's triangulation. With the --rig of a build "
                                   "(misaligned mirrors or a distorting lens) every map, the views and the "
                                   "disparities (also --min/--max-disparity) are in the rectified coordinates "
                                   "of the views (docs/optics.md): the left map on the left view's rectified "
                                   "grid, u'_l - u'_r px.")
    p.add_argument("image", metavar="IMAGE", help="complex image (PNG, grey)")
    p.add_argument("--rig", metavar="RIG.toml", help="rig file: disparity range from --near-mm..--far-mm, split "
                                                      "ratio, and the triangulation for --depth/--cloud")
    p.add_argument("--min-disparity", type=float, metavar="A", help="smallest disparity searched, px")
    p.add_argument("--max-disparity", type=float, metavar="B", help="largest disparity searched, px")
    p.add_argument("--near-mm", type=float, default=400.0, help="with --rig: working range near end (default 400)")
    p.add_argument("--far-mm", type=float, default=1200.0, help="with --rig: working range far end (default 1200)")
    p.add_argument("--split", type=float, metavar="S", help="right view's share s of the light (default: the "
                                                              "rig's split_ratio, else 0.5)")
    p.add_argument("-o", "--output", metavar="DISP.npy", required=True, help="left-view disparity map")
    p.add_argument("--right", metavar="DISP_R.npy", help="also the right view's disparity map")
    p.add_argument("--confidence", metavar="CONF.npy", help="also the left map's confidence (0..1)")
    p.add_argument("--views", nargs=2, metavar=("LEFT.png", "RIGHT.png"), help="separated left and right views")
    p.add_argument("--depth", metavar="DEPTH.npy", help="Z (mm) of each left-view pixel (needs --rig)")
    p.add_argument("--cloud", metavar="OUT.ply", help="point cloud, binary PLY, mm (needs --rig)")
    p.add_argument("--model", choices=MODELS, default=None,
                   help="triangulation model (default: refraction on the paper's geometry, exact on a build)")
    p.add_argument("--fast", action="store_true", help="half-resolution mode (docs/benchmarks.md)")
    p.set_defaults(run=run)


def _range(args, rig, rect, width: int) -> tuple[float, float]:
    if (args.min_disparity is None) != (args.max_disparity is None):
        raise ValueError("give both --min-disparity and --max-disparity, or neither (with --rig)")
    if args.min_disparity is not None:
        return args.min_disparity, args.max_disparity
    if rig is None:
        raise ValueError("give --rig or --min-disparity and --max-disparity")
    return disparity_range(rig, args.near_mm, args.far_mm, rect, width_px=width)


def run(args) -> int:
    out = check_output_path(args.output, (".npy",))
    right_out = check_output_path(args.right, (".npy",))
    conf_out = check_output_path(args.confidence, (".npy",))
    depth_out = check_output_path(args.depth, (".npy",))
    cloud_out = check_output_path(args.cloud, (".ply",))
    views = [check_output_path(v, (".png",)) for v in args.views] if args.views else None
    if (depth_out or cloud_out) and not args.rig:
        raise ValueError("--depth and --cloud need --rig (the triangulation)")
    rig = load_rig(args.rig) if args.rig else None
    split = args.split if args.split is not None else (rig.mirrors.split_ratio if rig else 0.5)
    if not 0.0 < split < 1.0:
        raise ValueError(f"--split must lie strictly between 0 and 1, got {split}")
    image = read_grey(args.image)
    rect = None
    if rig is not None:
        check_working_range(args.near_mm, args.far_mm)
        rect = rectification_for(rig, args.near_mm, args.far_mm)
        w, h = rig.camera.image_size_px
        if rect is not None and image.shape != (h, w):
            raise ValueError(f"image is {image.shape[1]}x{image.shape[0]} px but the rig's camera is {w}x{h} px "
                             "(a build's rectification needs the camera's full frame)")
    shape = image.shape if rect is None else rect.size_px[::-1]
    lo, hi = _range(args, rig, rect, shape[1])
    check_range(lo, hi, shape[1])
    params = FAST if args.fast else DEFAULT
    check_dense_memory(*shape, lo, hi, params,
                       "--min-disparity/--max-disparity" if args.max_disparity is not None else "the rig's range")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)
        if rig is None:
            dense = RigDense(dense_disparity(image, lo, hi, params=params), None, image)
        else:
            dense = dense_on_rig(image, rig, args.near_mm, args.far_mm, params=params, d_range=(lo, hi))
    res = dense.result
    for w in caught:
        print(f"psvs disparity: warning: {w.message}", file=sys.stderr)
    with output_batch():   # all outputs land together, or none replaces an earlier file
        write_npy(out, res.disparity_left)
        if right_out:
            write_npy(right_out, res.disparity_right)
        if conf_out:
            write_npy(conf_out, res.confidence_left)
        if views:
            if np.isfinite(res.disparity_left).any():
                lv, rv = separate_views(image, res.disparity_left, split, res.disparity_right, rect=dense.rect)
            else:  # nothing to separate by: a constant image is two identical constant views
                lv = rv = np.asarray(dense.left_image, dtype=np.float64)
            for path, v in zip(views, (lv, rv)):
                write_png(path, to_grey8(v))
        cloud = rig_cloud(dense, rig, args.model) if (depth_out or cloud_out) else None
        if depth_out:
            write_npy(depth_out, cloud.depth_mm.astype(np.float32))
        if cloud_out:
            write_cloud_ply(cloud_out, cloud, grey=dense.left_image)
    d = res.disparity_left[np.isfinite(res.disparity_left)]
    summary = (f"{d.size} of {res.disparity_left.size} px answered, disparity {np.median(d):.1f} px median "
               f"({res.searched_px[0]:.0f}..{res.searched_px[1]:.0f} searched)") if d.size else "no disparity found"
    print(f"{out}: {summary}" + (f"; {len(cloud.points_mm)} points" if cloud is not None else ""))
    return 0
