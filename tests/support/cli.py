"""Running psvs commands in-process from a test: :func:`run` calls the CLI's ``main`` and returns its exit
status and captured output; :data:`EXAMPLE` is the repository's default rig file."""
from pathlib import Path

from psvs.cli.main import main

#: examples/rigs/default.toml: the default rig as a file (the shipped ``default`` by path)
EXAMPLE = str(Path(__file__).resolve().parents[2] / "examples" / "rigs" / "default.toml")


def run(capsys, *argv):
    """``psvs ARGV`` in this process: (exit status, stdout, stderr), argparse's usage exits included."""
    try:
        code = main(list(argv))
    except SystemExit as exc:  # argparse usage errors
        code = exc.code
    out = capsys.readouterr()
    return code, out.out, out.err
