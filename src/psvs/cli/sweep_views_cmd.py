"""``psvs sweep-views``: a simulated robot sweep (the paper's calibration), ready for ``psvs calibrate``."""
from __future__ import annotations

import math

import numpy as np

from psvs.cli.common import add_rig_argument, rig_from_args
from psvs.io.atomic import check_output_folder


def add_parser(sub) -> None:
    p = sub.add_parser("sweep-views", help="render a robot sweep of the Fig. 9 pattern, for psvs calibrate",
                       description="Render the Fig. 9 pattern (five 10 mm circles, 20 mm apart) on a robot's holder "
                                   "(turned 2 and -3 deg, off-centre) at depths --from-mm..--to-mm every --step-mm "
                                   "through the rig, and write sweep_NNNN.png and sweep.csv (image, robot reading "
                                   "= depth + 312.7 mm) into DIR: the paper's calibration sweep as a robot makes it.")
    p.add_argument("folder", metavar="DIR", help="output folder (created if missing)")
    add_rig_argument(p)
    p.add_argument("--from-mm", type=float, default=425.0, help="nearest depth (default 425)")
    p.add_argument("--to-mm", type=float, default=1175.0, help="farthest depth (default 1175)")
    p.add_argument("--step-mm", type=float, default=50.0, help="robot step (default 50: 16 images)")
    p.add_argument("--seed", type=int, default=0, help="sensor noise (default 0)")
    p.set_defaults(run=run)


def run(args) -> int:
    from psvs.accuracy.table1 import ROBOT_OFFSET_MM, SUPERSAMPLE, check_pattern_depths, pattern_image
    from psvs.calibrate.sweep import dumps_sweep
    from psvs.io.atomic import output_batch, write_atomic
    from psvs.io.images import write_png
    from psvs.simulate.render import check_render_work

    for name in ("from_mm", "to_mm", "step_mm"):
        v = getattr(args, name)
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"--{name.replace('_', '-')} must be a finite number > 0 mm, got {v}")
    if args.to_mm < args.from_mm:
        raise ValueError(f"--to-mm ({args.to_mm} mm) must not be less than --from-mm ({args.from_mm} mm)")
    n = math.ceil((args.to_mm + 1e-9 - args.from_mm) / args.step_mm)   # np.arange's count, before any array
    if not 3 <= n <= 60:
        raise ValueError(f"the sweep has {n} positions; give 3-60 (--from-mm, --to-mm, --step-mm)")
    depths = np.round(args.from_mm + args.step_mm * np.arange(n), 6)    # 812.9, not 812.9000000000001
    names = _names(depths, args.step_mm)
    if args.seed < 0:
        raise ValueError(f"--seed must be >= 0, got {args.seed}")
    folder = check_output_folder(args.folder)
    rig = rig_from_args(args)
    check_pattern_depths(rig, float(depths[0]), float(depths[-1]), "--from-mm/--to-mm: the sweep's depths")
    check_render_work(rig, SUPERSAMPLE, n, f"the sweep's {n} positions", "fewer positions (a larger --step-mm)")
    images = [pattern_image(rig, float(z), args.seed + k) for k, z in enumerate(depths)]
    folder.mkdir(parents=True, exist_ok=True)
    rows = []
    with output_batch():            # the images and sweep.csv land together, or none of them
        for z, img, name in zip(depths, images, names, strict=True):
            write_png(folder / name, img)
            rows.append((name, round(float(z) - ROBOT_OFFSET_MM, 6)))
        write_atomic(folder / "sweep.csv", dumps_sweep(rows))
    stale = sorted(set(p.name for p in folder.glob("sweep_*.png")) - set(names))
    for name in stale:              # an earlier sweep's images: sweep.csv no longer lists them
        (folder / name).unlink(missing_ok=True)
    print(f"wrote {len(rows)} sweep images and sweep.csv to {folder}"
          + (f" (removed {len(stale)} image(s) of an earlier sweep)" if stale else ""))
    return 0


def _names(depths: np.ndarray, step_mm: float) -> list[str]:
    """The images' names, sweep_DDDD_d.png: each depth with as many decimals as the step has (at least one,
    at most six), so that no two positions share a name (a step of 0.05 mm wrote five positions into three files,
    each overwritten by the last; a trial)."""
    decimals = next((k for k in range(1, 7) if abs(round(step_mm, k) - step_mm) < 1e-9), 6)
    names = [f"sweep_{z:0{5 + decimals}.{decimals}f}.png".replace(".", "_", 1) for z in depths]
    if len(set(names)) != len(names):
        raise ValueError(f"--step-mm {step_mm:g} is finer than the images' names can tell apart (6 decimals of a mm)")
    return names
