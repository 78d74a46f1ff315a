"""``psvs`` entry point: one subcommand per module; bad input exits 2 with a one-line message.

A command's module is psvs.cli.<command>_cmd (dashes as underscores). ``psvs COMMAND ...`` imports only that
command's module, so a command starts without loading every other command's libraries (``psvs track``
must reach its first control cycle within 2 s); ``psvs --help`` and an unknown command load them all.
"""
from __future__ import annotations

import argparse
import importlib
import sys

from psvs.errors import MeasurementError, RigGeometryError

COMMANDS = ("demo", "rig", "design", "triangulate", "fit-refraction", "simulate", "match", "measure", "calibrate",
            "card-views", "sweep-views", "table1", "disparity", "dense-eval", "serve", "live", "handeye", "track",
            "replay", "export-calibration")


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse's usage errors: one line, exit 2
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The ``psvs`` parser with every command, or with the command ``only`` alone."""
    parser = _Parser(prog="psvs", description="Pseudo Stereo Vision System toolkit (Pachidis & Lygouras).")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser, required=True)
    for name in COMMANDS if only is None else (only,):
        importlib.import_module(f"psvs.cli.{name.replace('-', '_')}_cmd").add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    try:        # the command's module (and its libraries) load here: Ctrl-C then ends as it does later on
        parser = build_parser(argv[0] if argv and argv[0] in COMMANDS else None)
    except KeyboardInterrupt:
        print("\npsvs: interrupted", file=sys.stderr)
        return 130
    args = parser.parse_args(argv)
    try:
        return int(args.run(args) or 0)
    except KeyboardInterrupt:
        # Ctrl-C: one line and the shell's status for SIGINT; files are written atomically, so no output
        # is left half-written (a write in progress removes its temporary file)
        print(f"\npsvs {args.command}: interrupted", file=sys.stderr)
        return 130
    except MeasurementError as exc:     # well-formed input that cannot give a right answer: say why, no number
        print(f"psvs {args.command}: cannot measure: {_one_line(exc)}", file=sys.stderr)
        return 1
    except (ValueError, TypeError, OSError, RigGeometryError) as exc:
        msg = _one_line(exc)
        if isinstance(exc, OSError) and exc.filename and str(exc.filename) not in msg:
            msg = f"{msg}: {exc.filename}"
        print(f"psvs {args.command}: error: {msg}", file=sys.stderr)
        return 2


def _one_line(exc: BaseException) -> str:
    """An exception's message as one line (its first), or its type's name when it has none."""
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


if __name__ == "__main__":
    sys.exit(main())
