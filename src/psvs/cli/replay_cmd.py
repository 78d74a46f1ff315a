"""``psvs replay``: run the seam-tracking controller again on a ``psvs track --mcap`` recording."""
from __future__ import annotations

import sys

from psvs.cli.common import (
    add_rerun_arguments,
    add_rig_argument,
    check_rerun_arguments,
    measuring_rig,
    open_rerun,
)


def add_parser(sub) -> None:
    p = sub.add_parser("replay", help="run the seam-tracking controller on a recording and compare its commands",
                       description="The replay cell: a fresh seam sensor and controller run on the frames and "
                                   "flange poses of a psvs track --mcap recording, with its configuration, "
                                   "hand-eye transform and teach point; every command is compared with the "
                                   "recorded one, bit for bit. Exit 0 when all agree, 1 when some differ.")
    p.add_argument("recording", metavar="RECORDING.mcap", help="a psvs track --mcap file")
    add_rig_argument(p)
    add_rerun_arguments(p, serve=False)
    p.set_defaults(run=run)


def run(args) -> int:
    from pathlib import Path

    from psvs.robot.recording import replay_recording
    path = Path(args.recording)
    if path.is_dir():
        raise ValueError(f"{path} is a folder, not a recording (psvs track --mcap FILE.mcap)")
    if not path.is_file():
        raise FileNotFoundError(f"no such recording: {path}")
    check_rerun_arguments(args)
    if args.rerun is not None and Path(args.rerun).resolve() == path.resolve():
        raise ValueError("--rerun must not be the recording itself")
    rig = measuring_rig(args.rig)
    rec, cell = replay_recording(path, rig)
    with open_rerun(args, robot=True) as sink:
        if sink is not None:
            _rerun(sink, rec, cell)
    n = len(cell.sent)
    if rec.stop_reason is None:
        print("psvs replay: note: the recording ends without its /psvs/stop record (the run was cut short)",
              file=sys.stderr)
    if cell.mismatches:
        print(f"psvs replay: {len(cell.mismatches)} of {n} commands differ from the recording (first at cycle "
              f"{cell.mismatches[0]})", file=sys.stderr)
        return 1
    print(f"replayed {n} cycles: every command equals the recorded one"
          + (f" (the run's stop: {rec.stop_reason})" if rec.stop_reason else ""))
    return 0


def _rerun(sink, rec, cell) -> None:
    """--rerun: each replayed cycle's frame, the flange, camera and torch frames at its exposure, the torch
    path the replay commanded and whether its command differs from the recorded one."""
    import numpy as np

    from psvs.io.telemetry import BASE_FRAME, CAMERA_FRAME, FLANGE_FRAME, TORCH_FRAME
    from psvs.robot.mounting import tool2flange
    tool = tool2flange()
    torch = []
    differ = set(cell.mismatches)
    for k, (frame, sent) in enumerate(zip(cell.frames, cell.sent, strict=False)):
        t = frame.t_s
        sink.image(t, frame.image)
        sink.transforms(t, [(BASE_FRAME, FLANGE_FRAME, frame.flange2base), (FLANGE_FRAME, CAMERA_FRAME, rec.cam2flange),
                            (FLANGE_FRAME, TORCH_FRAME, tool)])
        torch.append(np.asarray(sent, float)[:3, 3])
        sink.lines(t, {"torch_commanded": np.array(torch[-500:])})
        sink.record("replay", t, {"cycle": k, "differs": k in differ})
