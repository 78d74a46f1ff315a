"""``psvs dense-eval``: score dense disparity on a superimposed real stereo pair with ground truth."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from psvs._budget import check_memory
from psvs.cli.common import check_distinct
from psvs.dense.compiled import announce_dense
from psvs.dense.evaluate import evaluate_pair, motorcycle
from psvs.dense.report import scores_markdown, write_report
from psvs.io.atomic import check_output_folder
from psvs.io.images import read_grey, read_image


def add_parser(sub) -> None:
    p = sub.add_parser("dense-eval", help="score dense disparity on a superimposed real stereo pair",
                       description="Superimpose a rectified stereo pair with ground truth as a PSVS would "
                                   "((1-s) L + s R), run `psvs disparity` on it and report bad-1, bad-2 and MAE "
                                   "beside OpenCV StereoSGBM on the separate pair, and the PSNR of the separated "
                                   "views. Default pair: Middlebury 2014 Motorcycle from scikit-image.")
    p.add_argument("--left", metavar="IM0.png", help="left image of your own pair (with --right and --truth)")
    p.add_argument("--right", metavar="IM1.png", help="right image")
    p.add_argument("--truth", metavar="DISP0.pfm",
                   help="left ground-truth disparity (.pfm or .npy; inf, NaN and 0 = none)")
    p.add_argument("--min-disparity", type=float, default=0.0, help="default 0")
    p.add_argument("--max-disparity", type=float, default=64.0, help="default 64")
    p.add_argument("--split", type=float, default=0.5, help="right view's share s (default 0.5)")
    p.add_argument("-o", "--output", metavar="DIR", help="write scores.json, report.md and figure.png here")
    p.set_defaults(run=run)


def _truth(path: str) -> np.ndarray:
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"ground truth not found: {p}")
    if p.suffix.lower() == ".npy":
        try:    # mapped, not read: a header claiming more data than the file holds is refused, not allocated
            gt = np.load(p, mmap_mode="r", allow_pickle=False)
        except (ValueError, EOFError) as exc:    # not an .npy file, or one cut short
            text = str(exc).strip()
            why = "its header claims more data than the file holds" if "mmap length" in text else \
                "no .npy header, or an array of Python objects" if "pickled" in text else text or "empty file"
            raise ValueError(f"not a readable .npy file: {p} ({why})") from None
        if gt.ndim == 2:
            check_memory(3 * 8 * gt.size, f"ground truth {p} ({gt.shape[1]}x{gt.shape[0]} px)")
    elif p.suffix.lower() == ".pfm":
        gt = read_image(p)          # its size checked from the header first; "not a readable image" otherwise
    else:
        raise ValueError(f"ground truth must be .pfm or .npy, got {p.name}")
    gt = np.array(gt, dtype=np.float64)      # a copy: the .npy is mapped read-only
    if gt.ndim != 2:
        raise ValueError(f"ground truth must be one channel (H, W), got shape {gt.shape}")
    gt[~np.isfinite(gt)] = np.nan
    zeros = int(np.sum(gt == 0.0))
    if zeros:       # KITTI's and Middlebury's older maps mark "no data" so; a PSVS measures no disparity 0
        gt[gt == 0.0] = np.nan
        print(f"psvs dense-eval: {zeros} ground-truth pixels of 0 px taken as none (a twin at its own pixel is no "
              "disparity a PSVS measures; 0 marks no data in KITTI's and Middlebury's older maps)", file=sys.stderr)
    return gt


def run(args) -> int:
    own = [args.left, args.right, args.truth]
    if any(own) and not all(own):
        raise ValueError("--left, --right and --truth go together")
    out = None if args.output is None else check_output_folder(args.output)
    check_distinct({"-o": args.output}, {"--left": args.left, "--right": args.right, "--truth": args.truth})
    if all(own):
        left, right, gt = read_grey(args.left), read_grey(args.right), _truth(args.truth)
        title = f"{Path(args.left).name} + {Path(args.right).name}"
        if not (left.shape == right.shape == gt.shape):
            raise ValueError(f"left {left.shape}, right {right.shape} and truth {gt.shape} differ in size")
    else:
        left, right, gt = motorcycle()
        title = "Middlebury 2014 Motorcycle (scikit-image), grey, full size"
    announce_dense("psvs dense-eval")
    ev = evaluate_pair(left, right, gt, args.min_disparity, args.max_disparity, args.split)
    print(scores_markdown(ev, f"{title}, split {args.split}, disparities "
                              f"{args.min_disparity:g}..{args.max_disparity:g}"))
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        for p in write_report(out, ev, title, args.max_disparity):
            print(f"wrote {p}")
    return 0
