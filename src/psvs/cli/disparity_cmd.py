"""``psvs disparity``: dense disparity (and separated views, depth, point cloud) of one complex image."""
from __future__ import annotations

import dataclasses
from dataclasses import replace

import numpy as np

from psvs.cli.common import (
    add_model_argument,
    add_range_arguments,
    add_rerun_arguments,
    check_distinct,
    check_output_path,
    check_rerun_arguments,
    measuring_model,
    measuring_rig,
    range_from_args,
)
from psvs.dense import Cloud, dense_disparity, write_cloud_ply
from psvs.dense.build import RigDense, dense_on_rig, rig_cloud, rig_depth, rig_trust
from psvs.dense.compiled import announce_dense
from psvs.dense.disparity import check_dense_memory, check_range, constant_refusal
from psvs.dense.params import DEFAULT, FAST, DenseParams
from psvs.dense.refusal import (
    elsewhere_words,
    mirror_words,
    nothing_answered,
    nothing_trusted,
    periodic_words,
    repeat_words,
)
from psvs.dense.rig_cache import rectification
from psvs.dense.separate import rig_views
from psvs.dense.trust import EchoTrust, trusted_maps
from psvs.errors import MeasurementError
from psvs.health.check import refuse_if_drifted, whole_check_due
from psvs.imaging.block_grid import check_block_grid
from psvs.imaging.grey import to_grey8
from psvs.io.atomic import output_batch
from psvs.io.images import check_frame_size, read_grey, write_npy, write_png
from psvs.optics.search_range import disparity_range


def add_parser(sub) -> None:
    p = sub.add_parser("disparity", help="dense disparity and view separation of a complex image",
                       description="Dense left-view disparity (u_l - u_r, px) of a complex image by its echoes "
                                   "(docs/dense.md). Writes a float32 HxW .npy, NaN where there is no answer; "
                                   "optionally the separated left and right views, the depth map and a point "
                                   "cloud through the rig's triangulation. With the --rig of a build "
                                   "(misaligned mirrors or a distorting lens) every map, the views and the "
                                   "disparities (also --min/--max-disparity) are in the rectified coordinates "
                                   "of the views (docs/optics.md): the left map on the left view's rectified "
                                   "grid, u'_l - u'_r px. The confidence map and the summary say which answers "
                                   "the echo supports beyond chance (surfaces where a patch correlates with its "
                                   "twin beyond what chance gives on the image itself, 1%% false alarm); when "
                                   "none does (noise, a blank wall) it exits 1 and writes nothing.")
    p.add_argument("image", metavar="IMAGE", help="complex image (PNG, grey)")
    p.add_argument("--rig", metavar="RIG.toml", help="rig file: disparity range from --near-mm..--far-mm, split "
                                                      "ratio, and the triangulation for --depth/--cloud")
    p.add_argument("--min-disparity", type=float, metavar="A", help="smallest disparity searched, px")
    p.add_argument("--max-disparity", type=float, metavar="B", help="largest disparity searched, px")
    add_range_arguments(p, "working range (with --rig)")
    p.add_argument("--split", type=float, metavar="S", help="right view's share s of the light (default: the "
                                                              "rig's split_ratio, else 0.5)")
    p.add_argument("-o", "--output", metavar="DISP.npy", required=True, help="left-view disparity map")
    p.add_argument("--right", metavar="DISP_R.npy", help="also the right view's disparity map")
    p.add_argument("--confidence", metavar="CONF.npy", help="also the left map's confidence (0..1; 0 where the "
                                                            "answer is not trusted: docs/dense.md)")
    p.add_argument("--views", nargs=2, metavar=("LEFT.png", "RIGHT.png"), help="separated left and right views")
    p.add_argument("--depth", metavar="DEPTH.npy", help="Z (mm) of each left-view pixel (needs --rig)")
    p.add_argument("--cloud", metavar="OUT.ply", help="point cloud, binary PLY, mm (needs --rig)")
    add_model_argument(p)
    p.add_argument("--fast", action="store_true", help="half-resolution mode (docs/benchmarks.md)")
    add_rerun_arguments(p, serve=False)
    p.set_defaults(run=run)


def _range(args, rig, rect, width: int) -> tuple[float, float]:
    if (args.min_disparity is None) != (args.max_disparity is None):
        raise ValueError("give both --min-disparity and --max-disparity, or neither (with --rig)")
    if args.min_disparity is not None:
        if getattr(args, "range_given", False):      # a trial's --near-mm 1000 was left unused without a word
            raise ValueError("give the disparities to search one way: --min-disparity/--max-disparity, or "
                             "--near-mm/--far-mm with --rig")
        return args.min_disparity, args.max_disparity
    if rig is None:
        raise ValueError("give --rig or --min-disparity and --max-disparity")
    return disparity_range(rig, args.near_mm, args.far_mm, rect, width_px=width)


def _outputs(args) -> dict:
    """Every output path, checked before any work (None where not asked for)."""
    rerun = getattr(args, "rerun", None)          # psvs batch has none
    if rerun is not None:
        check_rerun_arguments(args)
    out = {"disparity": check_output_path(args.output, (".npy",)), "right": check_output_path(args.right, (".npy",)),
           "rerun": rerun,
           "confidence": check_output_path(args.confidence, (".npy",)),
           "depth": check_output_path(args.depth, (".npy",)), "cloud": check_output_path(args.cloud, (".ply",)),
           "views": [check_output_path(v, (".png",)) for v in args.views] if args.views else None}
    named = {"-o": args.output, "--right": args.right, "--confidence": args.confidence, "--depth": args.depth,
             "--cloud": args.cloud, "--rerun": rerun}
    named.update({f"--views {i + 1}": v for i, v in enumerate(args.views or [])})
    check_distinct(named, {"IMAGE": args.image, "--rig": args.rig})
    if (out["depth"] or out["cloud"]) and not args.rig:
        raise ValueError("--depth and --cloud need --rig (the triangulation)")
    return out


def _inputs(args, image=None):
    """(rig or None, the image (H, W) uint8, the build's rectification or None, split, (lo, hi) px, params),
    checked against each other before any work. ``image``: already read (a frame of ``psvs batch``), else
    read from args.image."""
    rig = measuring_rig(args.rig) if args.rig else None
    split = args.split if args.split is not None else (rig.mirrors.split_ratio if rig else 0.5)
    if not 0.0 < split < 1.0:
        raise ValueError(f"--split must lie strictly between 0 and 1, got {split}")
    # another size than the rig's camera: every pixel's ray, and so the range and depths, would be wrong
    size = rig.camera.image_size_px if rig else None
    image = read_grey(args.image, expect_size=size) if image is None else check_frame_size(image, size, args.image)
    rect = None
    if rig is not None:
        near_mm, far_mm = range_from_args(args, rig)
        measuring_model(args, rig, near_mm, far_mm)
        rect = rectification(rig, near_mm, far_mm)     # with its remaps, from the cache when it holds them
    shape = image.shape if rect is None else rect.size_px[::-1]
    lo, hi = _range(args, rig, rect, shape[1])
    check_range(lo, hi, shape[1])
    params = FAST if args.fast else DEFAULT
    check_dense_memory(*shape, lo, hi, params,
                       "--min-disparity/--max-disparity" if args.max_disparity is not None else "the rig's range")
    return rig, image, rect, split, (lo, hi), params


def _write(out: dict, dense: RigDense, image, rig, split: float, model: str | None):
    """All the outputs asked for, together or none (an earlier file is replaced only when all are written);
    returns (the point cloud when a cloud or a Rerun recording was asked for, else None; the number of points
    in the cloud, else depths in the depth map, when either was asked for, else None). The cloud holds the
    trusted pixels' points only (confidence > 0), as the page and ``psvs live`` give them (an adversarial trial:
    a noisy frame's cloud held 260343 points, 85 % of them more than 2 % off, its 474 trusted ones unmarked);
    the depth map, like the disparity map, every answer (the confidence map says which are trusted)."""
    res = dense.result
    with output_batch():
        write_npy(out["disparity"], res.disparity_left)
        if out["right"]:
            write_npy(out["right"], res.disparity_right)
        if out["confidence"]:
            write_npy(out["confidence"], res.confidence_left)
        if out["views"]:           # the maps answer somewhere (_trusted)
            for path, v in zip(out["views"], rig_views(dense, rig, split), strict=True):
                write_png(path, to_grey8(v))
        want = out["cloud"] or (out["rerun"] and rig is not None)
        cloud = rig_cloud(dense, rig, model) if want else None
        if out["depth"]:           # depth alone needs no point list (psvs.dense.build.rig_depth)
            depth = cloud.depth_mm if cloud is not None else rig_depth(dense, rig, model)
            write_npy(out["depth"], depth.astype(np.float32))
        if cloud is not None:      # the trusted pixels' points
            trusted = res.confidence_left > 0
            u, v = cloud.pixels.T.astype(np.intp)
            keep = trusted[v, u]
            cloud = Cloud(cloud.points_mm[keep], cloud.pixels[keep], np.where(trusted, cloud.depth_mm, np.nan))
        points = len(cloud.points_mm) if cloud is not None else \
            int(np.count_nonzero(np.isfinite(depth))) if out["depth"] else None
        if out["cloud"]:
            write_cloud_ply(out["cloud"], cloud, grey=dense.left_image)
    return cloud, points


def _rerun(args, out: dict, dense: RigDense, cloud, image, rig) -> None:
    """--rerun: the complex image, the separated views, the maps, depth and the point cloud, and the rig."""
    from psvs.cli.common import open_rerun
    res = dense.result
    split = args.split if args.split is not None else (rig.mirrors.split_ratio if rig else 0.5)
    with open_rerun(args, keep_on_interrupt=False) as sink:     # one map: a recording cut short is no result
        if rig is not None:
            sink.rig(rig, args.near_mm, args.far_mm)
        sink.image(0.0, image)
        sink.views(0.0, *rig_views(dense, rig, split))
        sink.disparity(0.0, res.disparity_left, "disparity_left")
        if res.disparity_right is not None:
            sink.disparity(0.0, res.disparity_right, "disparity_right")
        if cloud is not None:
            sink.depth_image(0.0, cloud.depth_mm, "depth")
            sink.points(0.0, cloud.points_mm, topic="dense_points")


def _trusted(dense: RigDense) -> tuple[RigDense, EchoTrust]:
    """``dense`` with its confidence 0 where the echo does not support the answer beyond chance, and that
    judgement; MeasurementError when the maps answer nothing or nothing they answer is trusted
    (:mod:`psvs.dense.refusal`'s words)."""
    why = nothing_answered(dense)            # before the echo test: nothing to test
    if why:
        raise MeasurementError(why)
    trust = rig_trust(dense)
    why = nothing_trusted(dense, trust)
    if why:
        raise MeasurementError(why)
    return dataclasses.replace(dense, result=trusted_maps(dense.result, trust)), trust


def _checked_trust(dense: RigDense, image, rig, args, look, whole=None) -> tuple[RigDense, EchoTrust]:
    """:func:`_trusted`, and through a rig the image's whole self-check when the quick look before (``look``,
    :func:`_quick_look`) and the answer's strength call for it (:func:`psvs.health.check.whole_check_due`): a rig
    the image's twins say no longer fits it is refused in those words. ``whole``: when the search was pruned
    (:func:`_pruned`), a function giving the maps of the whole range, searched before anything is refused."""
    try:
        dense, trust = _trusted(dense)
    except MeasurementError as exc:
        if whole is not None:       # the prune is a shortcut: it must not refuse what the whole range shows
            return _checked_trust(whole(), image, rig, args, look)
        if rig is not None and whole_check_due(look, 0.0):
            refuse_if_drifted(image, rig, args.near_mm, args.far_mm, cause=exc)
        raise
    if rig is not None and whole_check_due(look, trust.count / dense.result.disparity_left.size):
        refuse_if_drifted(image, rig, args.near_mm, args.far_mm)
    return dense, trust


def _quick_look(image, rig, args):
    """Before any dense work through a rig: the image's twins on the rig's rows, read on a few tiles spread
    over the field (:func:`psvs.health.check.refuse_if_drifted`, quick): a rig they say the image has left
    (a knocked mirror, another build's or format's frame) is refused, confirmed by the whole check. A knock
    leaves the echo 20-50 % of a 1440 x 1080 map to trust, at depths a few percent off (an adversarial
    trial), so the answer's own strength cannot tell. The look, or None without a rig."""
    return None if rig is None else refuse_if_drifted(image, rig, args.near_mm, args.far_mm, quick=True)


def _summary(dense: RigDense, trust: EchoTrust) -> str:
    res = dense.result
    d = res.disparity_left[np.isfinite(res.disparity_left)]
    n = res.disparity_left.size
    return (f"{d.size} of {n} px answered, {trust.count} ({trust.count / n:.0%}) trusted (on surfaces whose echo "
            f"stands above chance: the strongest {trust.test.strongest_z:.1f} spreads, chance up to "
            f"{trust.test.strongest_threshold:.1f}), disparity {np.median(d):.1f} px median "
            f"({res.searched_px[0]:.0f}..{res.searched_px[1]:.0f} searched)"
            + (f"; part of the image echoes outside the range searched: {elsewhere_words(trust)}"
               if trust.elsewhere is not None and trust.elsewhere.any else "")
            + (f"; part of the image repeats along its rows: {repeat_words(trust)}"
               if trust.elsewhere is not None and trust.elsewhere.repeats else "")
            + (f"; part of the image's texture repeats along its rows: {periodic_words(trust)}"
               if trust.elsewhere is not None and trust.elsewhere.periodic_any else "")
            + (f"; part of the image's texture repeats at or beyond the range's end: {mirror_words(trust)}"
               if trust.elsewhere is not None and trust.elsewhere.mirrored_any else ""))


def prepare(args, image=None) -> tuple:
    """Every check of the command's arguments and inputs, before any work: (the output paths, the inputs of
    :func:`_inputs`). ``image``: already read (``psvs batch``), else read from args.image."""
    out = _outputs(args)
    return out, _inputs(args, image)


def compute(args, image=None, workspace=None, say_compiling: str | None = None) -> tuple[dict, RigDense,
                                                                                        EchoTrust, object]:
    """The command's work and its files: (output paths, the maps, their trust, (the point cloud or None, the
    number of points or None): see :func:`_write`).
    MeasurementError when the image is constant, or no answer stands above chance (nothing written). ``workspace``
    (psvs.dense.workspace.Workspace): kept from one frame to the next by ``psvs batch``'s workers;
    otherwise none (one call: each level's volumes are freed when the next level starts; a workspace keeps
    them all, about 250 MiB more at 2.3 MP). ``say_compiling``: the command's name, to say in a line, once
    its inputs are checked, that the dense kernels compile on this run (psvs.dense.compiled)."""
    out, (rig, image, rect, split, (lo, hi), params) = prepare(args, image)
    constant = constant_refusal(image)      # nothing to match: said before any work, nothing written
    if constant:
        raise MeasurementError(constant)
    check_block_grid(image)                 # JPEG's grid echoes at every 8 px lag: said before any work
    look = _quick_look(image, rig, args)
    if say_compiling:
        announce_dense(say_compiling)
    # a library warning is printed as one line by psvs.cli.main
    def search(p: DenseParams) -> RigDense:
        if rig is None:
            return RigDense(dense_disparity(image, lo, hi, params=p, workspace=workspace), None, image)
        given = getattr(args, "min_disparity", None) is not None      # else the working range's (lo, hi)
        return dense_on_rig(image, rig, args.near_mm, args.far_mm, params=p, d_range=(lo, hi) if given else None,
                            workspace=workspace)
    dense = search(params)
    whole = (lambda: search(_unpruned(params))) if _pruned(dense) else None
    dense, trust = _checked_trust(dense, image, rig, args, look, whole)
    written = _write(out, dense, image, rig, split, args.model)
    return out, dense, trust, written


def _pruned(dense: RigDense) -> bool:
    """Whether a coarse pass pruned the search (psvs.dense.prune) to less than the disparities asked for (by a
    lag or more at either end)."""
    lo, hi = dense.result.searched_px
    asked = dense.asked_px
    return asked is not None and (lo > asked[0] + 1.0 or hi < asked[1] - 1.0)


def _unpruned(p: DenseParams) -> DenseParams:
    """``p`` searching the whole range asked for, at every level (no coarse pass pruning it: an adversarial
    trial's circle-pattern card before a textured wall was refused by the pruned default mode, searched
    85-180 px, and answered over the whole 85-257 px: 136021 px trusted, 93.5 % of them within 2 % of Z)."""
    return replace(p, prune=False, top=None if p.top is None else replace(p.top, prune=False))


def summary_row(dense: RigDense, trust: EchoTrust) -> dict:
    """The figures of the summary line as scalars (a row of ``psvs batch``'s results)."""
    d = dense.result.disparity_left
    answered = np.isfinite(d)
    return {"answered_px": int(answered.sum()), "trusted_px": int(trust.count),
            "median_disparity_px": float(np.median(d[answered])) if answered.any() else None}


def run(args) -> int:
    with output_batch():    # the maps land with the recording or not at all (Ctrl-C while it is written)
        out, dense, trust, (cloud, points) = compute(args, say_compiling="psvs disparity")
        if out["rerun"]:
            rig = measuring_rig(args.rig) if args.rig else None
            _rerun(args, out, dense, cloud, read_grey(args.image), rig)
    print(f"{out['disparity']}: {_summary(dense, trust)}"
          + (f"; {points} {'points in the cloud (the trusted pixels)' if out['cloud'] else 'depths'}"
             if points is not None else ""))
    return 0
