"""SIGTERM and SIGHUP end a command as Ctrl-C does (issue 41 item 4): one line, exit 128 + the signal's
number, and no temporary file left where psvs was writing."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from psvs.cli.main import main

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_a_signal_mid_video_leaves_no_temporary_file(tmp_path, sig):
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    proc = subprocess.Popen([sys.executable, "-m", "psvs", "simulate", "fig5a", "--frames", "400", "-o",
                             str(tmp_path / "v.avi")], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            env=env)
    t0 = time.monotonic()
    while not list(tmp_path.iterdir()):           # the video's temporary file: frames are being written
        assert proc.poll() is None and time.monotonic() - t0 < 120, proc.stderr.read() if proc.poll() else "slow"
        time.sleep(0.05)
    proc.send_signal(sig)
    err = proc.communicate(timeout=60)[1]
    assert proc.returncode == 128 + sig, err
    assert err.strip().splitlines()[-1] == f"psvs simulate: terminated ({sig.name})"
    assert list(tmp_path.iterdir()) == []


def test_main_restores_the_callers_handlers(capsys):
    mine = signal.signal(signal.SIGTERM, signal.SIG_IGN)
    try:
        assert main(["rig", "list"]) == 0
        assert signal.getsignal(signal.SIGTERM) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGTERM, mine)
