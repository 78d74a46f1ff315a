"""``python -m psvs``: the command line. Ctrl-C while psvs is still loading ends like Ctrl-C later on:
one line and status 130 (the commands themselves handle it in :func:`psvs.cli.main.main`)."""
import sys

try:
    from psvs.cli.main import entry
except KeyboardInterrupt:
    print("\npsvs: interrupted", file=sys.stderr)
    raise SystemExit(130) from None

entry()
