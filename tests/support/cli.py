"""Running psvs commands in-process from a test: :func:`run` calls the CLI's ``main`` and returns its exit
status and captured output; :data:`EXAMPLE` is the repository's default rig file; :func:`user_cpu_s` is
the clock of the hang limits."""
import resource
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


def user_cpu_s() -> float:
    """The user-mode CPU time (s) this process has used, every thread: the clock of the tests' hang limits.
    Not the kernel's time: on a virtual machine the host backs memory the guest touches for the first time
    at ~100 MB/s, so one dense search (1.3 GB of volumes on 640x480) took 0.1 s of system time on one run
    and 12 s on the next, the same work. Nor the wall clock, which a machine busy with other work stretches."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_utime
