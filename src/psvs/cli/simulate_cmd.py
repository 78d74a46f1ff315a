"""``psvs simulate``: render a complex image of a scene (file or built-in) through a rig."""
from __future__ import annotations

import sys

import numpy as np

from psvs.cli.common import add_rig_argument, check_distinct, check_output_path, load_scene_spec, rig_from_args
from psvs.io.atomic import output_batch
from psvs.io.images import write_npz, write_png
from psvs.io.video import VIDEO_SUFFIXES, write_video
from psvs.simulate.builtin import describe
from psvs.simulate.render import check_render_work, check_supersample, render
from psvs.simulate.sensor import MAX_BLUR_PX, Sensor
from psvs.simulate.sequence import render_sequence, straight_path

#: The frame rates a video output is written at (trial 47: OpenCV's writer stored 1e9 as 600 while the line
#: said 1e+09, and 0.001 failed in FFmpeg with its own line on the terminal).
MIN_FPS, MAX_FPS = 0.1, 1000.0


def add_parser(sub) -> None:
    p = sub.add_parser("simulate", help="render a PSVS complex image of a scene",
                       description="Render the complex image of a scene through the exact optics: a scene file "
                                   "(TOML, docs/scene_file.md) or a built-in (see --list; parameters as "
                                   "name:key=value,...). Writes an 8-bit grey PNG and, with --truth, a .npz with "
                                   "each view's image, depth, disparity and validity.")
    p.add_argument("scene", metavar="SCENE", nargs="?", help="scene file (.toml) or built-in name")
    add_rig_argument(p, required=False)
    p.add_argument("-o", "--output", metavar="OUT.png", help="image to write (with --frames: OUT_000.png, ...; "
                                                           "OUT.avi or OUT.mkv: a lossless FFV1 video)")
    p.add_argument("--truth", metavar="OUT.npz", help="also write the ground truth")
    p.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    p.add_argument("--supersample", type=int, default=2, help="K x K samples per pixel (default 2)")
    p.add_argument("--blur-px", type=float, default=Sensor.blur_sigma_px, help="optical blur sigma, px")
    p.add_argument("--read-noise-e", type=float, default=Sensor.read_noise_e, help="read noise, electrons")
    p.add_argument("--full-well-e", type=float, default=Sensor.full_well_e, help="electrons at full scale")
    p.add_argument("--gain", type=float, default=Sensor.gain, help="digital gain")
    p.add_argument("--no-shot-noise", action="store_true", help="turn photon (shot) noise off")
    p.add_argument("--frames", type=int, default=1, help="render a sequence of N frames along --move-mm")
    p.add_argument("--move-mm", default="0,0,0", help="rig displacement over the sequence, 'dx,dy,dz' mm")
    p.add_argument("--fps", type=float, default=30.0, help="frame rate of a video output (default 30)")
    p.add_argument("--list", action="store_true", help="list the built-in scenes and exit")
    p.set_defaults(run=run)


def _move(text: str) -> np.ndarray:
    """--move-mm 'dx,dy,dz' as (3,) mm, or a one-line ValueError."""
    try:
        move = np.array([float(v) for v in text.split(",")])
    except ValueError:
        move = np.zeros(0)
    if move.shape != (3,) or not np.all(np.isfinite(move)):
        raise ValueError(f"--move-mm must be 'dx,dy,dz', three finite numbers in mm, got {text!r}")
    return move


def _write_truth(path, res, rig) -> None:
    """One frame's ground truth (.npz): both views, the irradiance, depths, disparities, validity."""
    t = res.truth
    write_npz(path, left=res.left.astype(np.float32), right=res.right.astype(np.float32),
              irradiance=res.irradiance.astype(np.float32), depth_left_mm=t.depth_left_mm,
              depth_right_mm=t.depth_right_mm, disparity_left_px=t.disparity_left_px,
              disparity_right_px=t.disparity_right_px, valid_left=t.valid_left, valid_right=t.valid_right,
              split_ratio=rig.mirrors.split_ratio)


def run(args) -> int:
    if args.list:
        for name, doc, params in describe():
            print(f"{name:<10} {doc}\n{'':<10} parameters: {params}")
        return 0
    if args.scene is None or args.output is None:
        raise ValueError("give a SCENE and -o OUT.png (or --list)")
    out = check_output_path(args.output, (".png", *VIDEO_SUFFIXES))
    video = out.suffix.lower() in VIDEO_SUFFIXES
    if video and not MIN_FPS <= args.fps <= MAX_FPS:
        raise ValueError(f"--fps must be {MIN_FPS:g}..{MAX_FPS:g} frames/s (what an FFV1 AVI holds), "
                         f"got {args.fps:g}")
    truth_path = check_output_path(args.truth, (".npz",))
    check_distinct({"-o": args.output, "--truth": args.truth}, {"SCENE": args.scene, "--rig": args.rig})
    if args.frames < 1:
        raise ValueError(f"--frames must be >= 1, got {args.frames}")
    move = _move(args.move_mm)
    if args.seed is not None and args.seed < 0:
        raise ValueError(f"--seed must be >= 0, got {args.seed}")
    if not args.blur_px <= MAX_BLUR_PX:
        raise ValueError(f"--blur-px must be at most {MAX_BLUR_PX:g} px (a lens's blur), got {args.blur_px}")
    sensor = Sensor(args.blur_px, args.full_well_e, args.read_noise_e, args.gain, not args.no_shot_noise)
    rig = rig_from_args(args)
    check_supersample(rig, args.supersample, "--supersample")
    check_render_work(rig, args.supersample, args.frames, f"--frames {args.frames} x --supersample {args.supersample}",
                      "fewer --frames or a smaller --supersample", truth=truth_path is not None)
    scene = load_scene_spec(args.scene)
    if args.frames > 1:     # the frames (a PNG sequence) and the truth files each numbered _NNN
        _check_no_longer_sequence([*([] if video else [out]), *([truth_path] if truth_path is not None else [])],
                                  args.frames)
    if args.frames == 1 and not video:
        results = [render(scene, rig, supersample=args.supersample, sensor=sensor, seed=args.seed,
                          truth=truth_path is not None)]
        names = [out]
    else:
        results = render_sequence(scene, rig, straight_path([0, 0, 0], move, args.frames),
                                  supersample=args.supersample, sensor=sensor, seed=args.seed,
                                  truth=truth_path is not None)
        names = [out.with_name(f"{out.stem}_{i:03d}.png") for i in range(args.frames)]

    def frames():
        for i, (res, name) in enumerate(zip(results, names, strict=True)):
            if not video:
                write_png(name, res.image)
            if truth_path is not None:
                _write_truth(truth_path if args.frames == 1 else
                             truth_path.with_name(f"{truth_path.stem}_{i:03d}.npz"), res, rig)
            h, w = res.image.shape
            said = f"{w}x{h}, mean grey {res.image.mean():.1f}"
            if args.frames == 1 and not video:
                single.append(f"{name}: {said}")
            else:   # progress, honest if a later frame is refused: rendered, not yet written (it lands whole)
                print(f"frame {i} rendered{'' if video else f' ({name.name})'}: {said}", file=sys.stderr)
            yield res.image

    single: list[str] = []
    if video:
        n = write_video(out, frames(), fps=args.fps)
        print(f"wrote {out}: {n} frames, FFV1, {args.fps:g} frames/s", file=sys.stderr)
    else:
        with output_batch():     # a sequence lands whole or not at all (an interrupted run leaves the old one)
            n = sum(1 for _ in frames())
        print(single[0] if single else f"wrote {names[0].name} ... {names[-1].name}: {n} frames", file=sys.stderr)
    return 0


def _check_no_longer_sequence(outs: list, frames: int) -> None:
    """ValueError when files of an older, longer sequence (OUT_NNN.png or TRUTH_NNN.npz, each of ``outs``
    numbered from ``frames`` up, with any number of digits) would stay beside the new ones: a folder mixing two
    runs' frames, or frames with another run's truth, is no sequence."""
    for out in outs:
        numbered = ((q.stem.rsplit("_", 1)[1], q) for q in out.parent.glob(f"{out.stem}_*{out.suffix}"))
        stale = sorted((int(k), q.name) for k, q in numbered if k.isdigit() and int(k) >= frames)
        if stale:
            raise ValueError(f"{out.parent} holds {len(stale)} file(s) of a longer sequence ({stale[0][1]} ...) "
                             f"that would stay beside these {frames}: remove them or choose another "
                             f"{'--truth' if out.suffix == '.npz' else '-o'} name")
