"""The console script's ending (psvs.cli.main.end_process): the status, everything printed, the exit handlers
run, and a thread still working is waited for, as the interpreter's own ending would; run in child processes."""
from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest


def _child(body: str, tmp_path) -> subprocess.CompletedProcess:
    code = textwrap.dedent(body)
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=tmp_path)


def test_status_output_and_exit_handlers_survive_the_quick_ending(tmp_path):
    res = _child("""
        import atexit, sys
        from pathlib import Path
        from psvs.cli.main import end_process
        atexit.register(lambda: Path("handler.txt").write_text("ran"))
        sys.stdout.write("x" * 100000)           # more than a pipe's buffer: must all arrive
        print("last line", file=sys.stderr, end="")
        end_process(3)
        """, tmp_path)
    assert res.returncode == 3
    assert res.stdout == "x" * 100000
    assert res.stderr == "last line"
    assert (tmp_path / "handler.txt").read_text() == "ran"


def test_a_thread_still_working_is_waited_for(tmp_path):
    res = _child("""
        import threading, time
        from pathlib import Path
        from psvs.cli.main import end_process
        def work():
            time.sleep(0.5)
            Path("thread.txt").write_text("done")
        threading.Thread(target=work).start()
        end_process(0)
        """, tmp_path)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "thread.txt").read_text() == "done"


def test_the_installed_command_and_python_m_end_with_the_commands_status(tmp_path):
    for argv in ([sys.executable, "-m", "psvs", "disparity", str(tmp_path / "none.png"), "-o", "d.npy"],
                 [sys.executable, "-m", "psvs", "design", "--rig", "default"]):
        res = subprocess.run(argv, capture_output=True, text=True, timeout=300, cwd=tmp_path)
        if "none.png" in argv[4]:
            assert res.returncode == 2
            said = f"psvs disparity: error: image not found: {tmp_path / 'none.png'}"
            assert res.stderr.strip().splitlines() == [said]
        else:
            assert res.returncode == 0, res.stderr
            assert "M1" in res.stdout


def _psvs(argv, tmp_path, unbuffered: bool, **kw) -> subprocess.Popen:
    env = dict(os.environ)
    env.pop("PYTHONUNBUFFERED", None)
    if unbuffered:
        env["PYTHONUNBUFFERED"] = "1"
    return subprocess.Popen([sys.executable, "-m", "psvs", *argv], cwd=tmp_path, env=env, stderr=subprocess.PIPE,
                            text=True, **kw)


@pytest.mark.parametrize("argv", [["rig", "show", "default"], ["rig", "--help"]])    # --help: argparse's own exit
@pytest.mark.parametrize("unbuffered", [False, True])
def test_output_to_a_full_disk_is_one_line_and_status_2(tmp_path, unbuffered, argv):
    with open("/dev/full", "w") as full:
        proc = _psvs(argv, tmp_path, unbuffered, stdout=full)
        _, err = proc.communicate(timeout=120)
    assert proc.returncode == 2
    assert len(err.strip().splitlines()) == 1 and err.startswith("psvs rig: error: ") and "No space left" in err, err


@pytest.mark.parametrize("unbuffered", [False, True])
def test_output_to_a_reader_gone_is_status_141_and_nothing_said(tmp_path, unbuffered):
    proc = _psvs(["rig", "show", "default"], tmp_path, unbuffered, stdout=subprocess.PIPE)
    proc.stdout.close()                                  # the reader went away before anything was written
    err = proc.stderr.read()
    assert proc.wait(timeout=120) == 141 and err == ""


@pytest.mark.parametrize("unbuffered", [False, True])
def test_a_large_result_cut_short_by_the_disk_is_an_error(tmp_path, unbuffered):
    """PYTHONUNBUFFERED: the text layer ignored a short write's count, 2 MB of 18.7 MB kept at exit 0 (trial 48)."""
    rng = np.random.default_rng(0)
    v, u = rng.uniform(50, 400, 60000), rng.uniform(300, 600, 60000)
    rows = np.column_stack([u, v, u - rng.uniform(90, 250, 60000), v])
    np.savetxt(tmp_path / "pairs.csv", rows, fmt="%.3f", delimiter=",", header="u_l,v_l,u_r,v_r", comments="")

    def small_files():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (200_000, 200_000))

    with open(tmp_path / "out.csv", "w") as out:
        proc = _psvs(["triangulate", "--rig", "default", "pairs.csv"], tmp_path, unbuffered, stdout=out,
                     preexec_fn=small_files)
        _, err = proc.communicate(timeout=300)
    assert proc.returncode == 2, err
    assert len(err.strip().splitlines()) == 1 and err.startswith("psvs triangulate: error: ") and "too large" in err


@pytest.mark.parametrize("unbuffered", [False, True])
def test_a_full_disk_without_a_stderr_is_still_status_2(tmp_path, unbuffered):
    """No stderr to say it on (closed): the status says it (trial 48's review: exit 0, and 120 unbuffered)."""
    with open("/dev/full", "w") as full:
        proc = _psvs(["rig", "show", "default"], tmp_path, unbuffered, stdout=full, preexec_fn=lambda: os.close(2))
        proc.communicate(timeout=120)
    assert proc.returncode == 2
