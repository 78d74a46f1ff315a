"""The console script's ending (psvs.cli.main.end_process): the status, everything printed, the exit handlers
run, and a thread still working is waited for, as the interpreter's own ending would; run in child processes."""
from __future__ import annotations

import subprocess
import sys
import textwrap


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
