"""``psvs`` entry point: one subcommand per module; bad input exits 2 with a one-line message."""
from __future__ import annotations

import argparse
import sys

from psvs.cli import (calibrate_cmd, card_views_cmd, demo_cmd, dense_eval_cmd, design_cmd, disparity_cmd,
                      export_calibration_cmd, fit_refraction_cmd, handeye_cmd, live_cmd, match_cmd, measure_cmd,
                      replay_cmd, rig_cmd, serve_cmd, simulate_cmd, sweep_views_cmd, table1_cmd, track_cmd,
                      triangulate_cmd)
from psvs.errors import RigGeometryError

COMMANDS = (demo_cmd, rig_cmd, design_cmd, triangulate_cmd, fit_refraction_cmd, simulate_cmd, match_cmd,
            measure_cmd, calibrate_cmd, card_views_cmd, sweep_views_cmd, table1_cmd, disparity_cmd, dense_eval_cmd,
            serve_cmd, live_cmd, handeye_cmd, track_cmd, replay_cmd, export_calibration_cmd)


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse's usage errors: one line, exit 2
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="psvs", description="Pseudo Stereo Vision System toolkit (Pachidis & Lygouras).")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser, required=True)
    for mod in COMMANDS:
        mod.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.run(args) or 0)
    except KeyboardInterrupt:
        # Ctrl-C: one line and the shell's status for SIGINT; files are written atomically, so no output
        # is left half-written (a write in progress removes its temporary file)
        print(f"\npsvs {args.command}: interrupted", file=sys.stderr)
        return 130
    except (ValueError, TypeError, OSError, RigGeometryError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if isinstance(exc, OSError) and exc.filename and str(exc.filename) not in msg:
            msg = f"{msg}: {exc.filename}"
        print(f"psvs {args.command}: error: {msg}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
