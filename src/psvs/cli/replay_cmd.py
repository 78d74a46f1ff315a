"""``psvs replay``: run the seam-tracking controller again on a ``psvs track --mcap`` recording."""
from __future__ import annotations

import sys

from psvs.cli.common import add_rig_argument, rig_from_args


def add_parser(sub) -> None:
    p = sub.add_parser("replay", help="run the seam-tracking controller on a recording and compare its commands",
                       description="The replay cell: a fresh seam sensor and controller run on the frames and "
                                   "flange poses of a psvs track --mcap recording, with its configuration, "
                                   "hand-eye transform and teach point; every command is compared with the "
                                   "recorded one, bit for bit. Exit 0 when all agree, 1 when some differ.")
    p.add_argument("recording", metavar="RECORDING.mcap", help="a psvs track --mcap file")
    add_rig_argument(p)
    p.set_defaults(run=run)


def run(args) -> int:
    from pathlib import Path

    from psvs.robot.recording import replay_recording
    path = Path(args.recording)
    if path.is_dir():
        raise ValueError(f"{path} is a folder, not a recording (psvs track --mcap FILE.mcap)")
    if not path.is_file():
        raise FileNotFoundError(f"no such recording: {path}")
    rig = rig_from_args(args)
    rec, cell = replay_recording(path, rig)
    n = len(cell.sent)
    if rec.stop_reason is None:
        print("note: the recording ends without its /psvs/stop record (the run was cut short)", file=sys.stderr)
    if cell.mismatches:
        print(f"{len(cell.mismatches)} of {n} commands differ from the recording (first at cycle "
              f"{cell.mismatches[0]})", file=sys.stderr)
        return 1
    print(f"replayed {n} cycles: every command equals the recorded one"
          + (f" (the run's stop: {rec.stop_reason})" if rec.stop_reason else ""))
    return 0
