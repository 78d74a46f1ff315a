"""``psvs card-views``: simulated views of a hand-held circle-grid card, ready for ``psvs calibrate``."""
from __future__ import annotations

import os
import re
import shutil
import tempfile
from pathlib import Path

from psvs.cli.common import add_rig_argument, rig_from_args
from psvs.io.atomic import check_output_folder

#: Samples per pixel side of each view (render_grid_shots' default).
RENDER_SUPERSAMPLE = 2
#: --video: frames a pose is held, moving frames between poses, renders per moving frame, and one pose in
#: OUT_EVERY held partly out of the image (psvs.calibrate.handheld).
HOLD_FRAMES, MOVE_FRAMES, BLUR_SAMPLES, OUT_EVERY = 3, 1, 3, 7


def add_parser(sub) -> None:
    p = sub.add_parser("card-views", help="render hand-held card views through a rig, for psvs calibrate",
                       description="Render N views of a circle-grid card (4x6 discs, 14 mm apart, 7 mm across, "
                                   "unless --rows/--cols/--spacing-mm/--diameter-mm, or any target --target "
                                   "describes) at random poses (450-1000 mm, "
                                   "tilted up to 25 deg) through the rig, and write card_NN.png and target.toml into "
                                   "DIR: a calibration folder as a user would make with a printed card.")
    p.add_argument("folder", metavar="DIR", help="output folder (created if missing)")
    add_rig_argument(p)
    p.add_argument("--views", type=int, default=16, help="number of views (3-60, default 16)")
    p.add_argument("--seed", type=int, default=0, help="random poses and sensor noise (default 0)")
    p.add_argument("--rows", type=int, default=4)
    p.add_argument("--cols", type=int, default=6)
    p.add_argument("--spacing-mm", type=float, default=14.0)
    p.add_argument("--diameter-mm", type=float, default=7.0)
    p.add_argument("--video", metavar="FILE.avi", help="instead of still views, a hand-held video (lossless FFV1, "
                                                      "30 frames/s): the card held still at --views poses "
                                                      f"({HOLD_FRAMES} frames each) at 400-900 mm, moved smoothly "
                                                      "between them (motion-blurred), one pose in "
                                                      f"{OUT_EVERY} partly out of the image; DIR gets target.toml "
                                                      "(for psvs capture)")
    p.add_argument("--target", metavar="TARGET.toml",
                   help="render this target instead (any kind psvs calibrate reads: circle_grid, "
                        "asymmetric_circle_grid, charuco; docs/calibration.md)")
    p.add_argument("--interleave", action="store_true",
                   help="let the card's two copies interleave, as a hand-held card wider than its disparity does")
    p.set_defaults(run=run)


def run(args) -> int:
    from psvs.calibrate.synthetic import check_card_fits, random_poses, render_grid_shots
    from psvs.io.atomic import write_atomic
    from psvs.io.images import write_png
    from psvs.simulate.render import check_render_work
    from psvs.simulate.textures import CircleGrid
    from psvs.targets.target_file import dumps_target

    if not 3 <= args.views <= 60:
        raise ValueError(f"--views must be 3-60, got {args.views}")
    if args.seed < 0:
        raise ValueError(f"--seed must be >= 0, got {args.seed}")
    folder = check_output_folder(args.folder)
    if not args.video:
        _check_replaceable(folder)
    if args.target is not None:
        from psvs.targets.target_file import load_target
        card = load_target(args.target)
    else:
        try:
            card = CircleGrid(args.rows, args.cols, args.spacing_mm, args.diameter_mm)
        except ValueError as exc:
            raise ValueError(f"card: {str(exc).replace('_mm', '-mm')}") from None
    rig = rig_from_args(args)
    apart = not args.interleave
    if args.video and (args.interleave or not isinstance(card, CircleGrid)):
        raise ValueError("--video renders a circle-grid card held apart from its copy: not with --interleave or "
                         "another kind of --target")
    if isinstance(card, CircleGrid):
        try:   # before any pose is tried: a card no pose shows would be searched for 2000 times a view
            check_card_fits(rig, card, args.views, (400.0, 900.0) if args.video else (450.0, 1000.0), apart=apart)
        except ValueError as exc:
            raise ValueError(f"card (--rows {card.rows} --cols {card.cols} --spacing-mm {card.spacing_mm:g} "
                             f"--diameter-mm {card.diameter_mm:g}): {exc}") from None
    if args.video:
        return _video(args, rig, card, folder)
    check_render_work(rig, RENDER_SUPERSAMPLE, args.views, f"--views {args.views}", "fewer --views")
    poses = random_poses(rig, card, args.views, seed=args.seed, apart=apart)
    shots = render_grid_shots(rig, card, poses, seed=args.seed, supersample=RENDER_SUPERSAMPLE)
    folder.parent.mkdir(parents=True, exist_ok=True)
    new = Path(tempfile.mkdtemp(prefix=f".{folder.name}.new-", dir=folder.parent))
    try:
        for k, shot in enumerate(shots):
            write_png(new / f"card_{k:02d}.png", shot.image)
        write_atomic(new / "target.toml", dumps_target(card))
        _replace_folder(new, folder)
    finally:
        shutil.rmtree(new, ignore_errors=True)
    print(f"wrote {len(shots)} card views and target.toml to {folder}")
    return 0


def _written_here(name: str) -> bool:
    return name == "target.toml" or re.fullmatch(r"card_\d{2}\.png", name) is not None


def _check_replaceable(folder: Path) -> None:
    """ValueError when ``folder`` holds anything but an earlier set of card views (card_NN.png, target.toml):
    the new set replaces a whole earlier set, never mixes into other files (a calibration reads every image
    of the folder)."""
    if not folder.is_dir():
        return
    other = sorted(p.name for p in folder.iterdir() if not _written_here(p.name))
    if other:
        shown = ", ".join(other[:3]) + (f" and {len(other) - 3} more" if len(other) > 3 else "")
        raise ValueError(f"{folder} holds files card-views did not write ({shown}): a calibration reads every image "
                         "of its folder, so the new views would mix with them; give a new or empty folder")


def _replace_folder(new: Path, folder: Path) -> None:
    """``folder`` becomes ``new`` whole: an earlier set of card views (checked by :func:`_check_replaceable`)
    moved aside, the new set moved in, the earlier one removed; a set is never mixed with another."""
    if not folder.exists():
        os.replace(new, folder)
        return
    _check_replaceable(folder)                      # still only an earlier set
    old = Path(tempfile.mkdtemp(prefix=f".{folder.name}.old-", dir=folder.parent))
    os.replace(folder, old / "set")
    os.replace(new, folder)
    shutil.rmtree(old, ignore_errors=True)


def _video(args, rig, card, folder) -> int:
    """--video: a simulated hand-held video of the card, and target.toml in the folder."""
    from psvs.calibrate.handheld import HandParams, hand_path, render_hand_video
    from psvs.cli.common import check_distinct, check_output_path
    from psvs.io.atomic import output_batch, write_atomic
    from psvs.io.video import VIDEO_SUFFIXES, write_video
    from psvs.simulate.render import check_render_work
    from psvs.targets.target_file import dumps_target
    video = check_output_path(args.video, VIDEO_SUFFIXES)
    check_distinct({"--video": video, "DIR/target.toml": folder / "target.toml"}, {"--rig": args.rig})
    renders = args.views + (args.views - 1) * MOVE_FRAMES * BLUR_SAMPLES
    check_render_work(rig, 1, renders, f"--views {args.views} (a video of {renders} renders)", "fewer --views")
    hand = HandParams(HOLD_FRAMES, MOVE_FRAMES, BLUR_SAMPLES, OUT_EVERY)
    path = hand_path(rig, card, args.views, seed=args.seed, hand=hand)
    folder.mkdir(parents=True, exist_ok=True)
    with output_batch():
        write_atomic(folder / "target.toml", dumps_target(card))
        n = write_video(video, render_hand_video(rig, card, path, seed=args.seed))
    print(f"wrote a {n}-frame hand-held video of the card at {args.views} poses to {video}, and target.toml to "
          f"{folder}")
    return 0
