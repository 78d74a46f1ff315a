"""Ctrl-C: one line, exit status 130, no traceback and no partial file -- from ``psvs`` and
from ``dev.py``, which passes the signal on and waits for psvs instead of killing it."""
import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("launcher", ["psvs", "dev.py"])
def test_ctrl_c_during_table1(tmp_path, launcher):
    out = tmp_path / "t1"
    cmd = [sys.executable, "-m", "psvs"] if launcher == "psvs" else [sys.executable, str(ROOT / "dev.py"), "psvs"]
    # SIGINT as a terminal's foreground job has it: a test run from a background job (where the shell set
    # SIGINT to "ignored", which children inherit) must not make the child deaf to Ctrl-C
    proc = subprocess.Popen(cmd + ["table1", "-o", str(out)], cwd=tmp_path, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    # wait until table1 is at work (its progress bar has counted a first sweep image), at most 20 s (the
    # run takes > 30 s; dev.py may first reinstall the virtualenv), then interrupt it
    seen = b""
    t0 = time.monotonic()
    while b"] 1/" not in seen and time.monotonic() - t0 < 20:
        assert proc.poll() is None, seen.decode(errors="replace")[-2000:]
        ready, _, _ = select.select([proc.stderr], [], [], 0.5)
        if ready:
            seen += os.read(proc.stderr.fileno(), 65536)
    assert proc.poll() is None, "table1 ended before it could be interrupted"
    proc.send_signal(signal.SIGINT)      # to this process only: dev.py must pass it on
    rest = proc.communicate(timeout=120)[1]
    err = (seen + rest).decode(errors="replace")
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    # one line: from the command, or from `python -m psvs` when the signal came while psvs was loading
    assert err.strip().splitlines()[-1] in ("psvs table1: interrupted", "psvs: interrupted")
    assert [p.name for p in out.iterdir()] == [] if out.exists() else True
