"""No traceback ever reaches a user: a result (exit 0), or one line on stderr and a non-zero status -- bad
input 2, anything unexpected 1 as an "internal error" (PSVS_DEBUG=1 shows its traceback) -- and only psvs's
own words: no OpenCV log, no libpng line, no numpy RuntimeWarning. ``capfd`` sees what C code writes to
file descriptor 2 as well as Python's stderr."""
import os
import struct
import subprocess
import sys
import warnings
import zlib
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from psvs._quiet import quiet_libraries
from psvs.cli.main import main
from psvs.io.images import write_png
from tests.support.cli import EXAMPLE

ROOT = Path(__file__).resolve().parents[2]
EARLIER = "earlier contents\n"


def run(capfd, *argv):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:  # argparse usage errors
        code = exc.code
    out, err = capfd.readouterr()
    return code, out, err


def one_line(code, err, status, expected):
    assert code == status, err
    assert len(err.strip().splitlines()) == 1, err
    assert expected in err, err
    assert "Traceback" not in err and "WARN" not in err and "RuntimeWarning" not in err


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Inputs every failure class needs, written once."""
    d = tmp_path_factory.mktemp("inputs")
    noise = np.random.default_rng(3).integers(0, 256, (480, 640)).astype(np.uint8)
    write_png(d / "ok.png", noise)
    data = (d / "ok.png").read_bytes()
    (d / "cut.png").write_bytes(data[: len(data) // 2])
    bomb = bytearray(data)
    bomb[16:24] = struct.pack(">II", 100000, 100000)
    bomb[29:33] = struct.pack(">I", zlib.crc32(bytes(bomb[12:29])))
    (d / "bomb.png").write_bytes(bytes(bomb))
    (d / "text.png").write_text("not an image\n")
    (d / "deep.toml").write_text("a = " + "[" * 5000 + "]" * 5000 + "\n")
    (d / "deep.json").write_text("[" * 100000 + "]" * 100000)
    (d / "digits.json").write_text('{"camera": {"focal_length_mm": ' + "9" * 5000 + "}}")
    (d / "binary.toml").write_bytes(data)
    (d / "mesh_scene.toml").write_text('[[objects]]\ntype = "mesh"\nfile = "ok.png"\n')
    (d / "notvideo.avi").write_text("not a video\n")
    text = Path(EXAMPLE).read_text(encoding="utf-8")
    (d / "bom.toml").write_text("\ufeff" + text, encoding="utf-8")
    big = "\n".join("focal_length_mm = 1e308" if ln.startswith("focal_length_mm") else ln for ln in text.splitlines())
    (d / "huge_focal.toml").write_text(big + "\n")
    (d / "bom.csv").write_bytes(b"\xef\xbb\xbfu_l,v_l,u_r,v_r\r\n435.2326270743,239.5,206.5,239.5\r\n")
    np.save(d / "full.npy", np.zeros((480, 640)))
    (d / "lying.npy").write_bytes((d / "full.npy").read_bytes()[:4000])
    return d


@pytest.fixture
def earlier(tmp_path):
    """An output file from an earlier run, which a failing command must leave as it was."""
    def make(name):
        path = tmp_path / name
        path.write_text(EARLIER)
        return path
    return make


@pytest.mark.parametrize("argv, output, expected", [
    (["match", "{ok.png}", "--rig", "{deep.toml}", "--auto", "-o"], "m.json",
     "deep.toml: malformed TOML: nested too deep"),
    (["simulate", "fig9", "--rig", "{deep.json}", "-o"], "s.png", "deep.json: malformed JSON: nested too deep"),
    (["simulate", "fig9", "--rig", "{digits.json}", "-o"], "s.png",
     "digits.json: malformed JSON: Exceeds the limit (4300 digits) for integer string conversion: value has 5000"),
    (["simulate", "fig9", "--rig", "{binary.toml}", "-o"], "s.png",
     "binary.toml: not a TOML file (it is not UTF-8 text; an image?)"),
    (["simulate", "{mesh_scene.toml}", "-o"], "s.png",
     "mesh_scene.toml: objects[0].file: not a mesh trimesh can read (STL, OBJ, PLY, ...): "),
    (["disparity", "{bomb.png}", "--min-disparity", "0", "--max-disparity", "9", "-o"], "d.npy",
     "bomb.png: image is 100000x100000 px (10000 megapixels), more than the 100 megapixels psvs reads"),
    (["match", "{bomb.png}", "--rig", EXAMPLE, "--auto", "-o"], "m.json",
     "bomb.png: image is 100000x100000 px but the rig's camera is 640x480 px"),
    (["match", "{cut.png}", "--rig", EXAMPLE, "--auto", "-o"], "m.json", "cut.png (libpng error: "),
    (["disparity", "{text.png}", "--min-disparity", "0", "--max-disparity", "9", "-o"], "d.npy",
     "not a readable image: {text.png} (not a PNG, JPEG, BMP, TIFF or PNM"),
    (["dense-eval", "--left", "{ok.png}", "--right", "{ok.png}", "--truth", "{lying.npy}", "-o"], "out/",
     "not a readable .npy file: {lying.npy} (its header claims more data than the file holds)"),
    (["live", "--video", "{notvideo.avi}", "--rig", "default", "--dense", "-o"], "log.csv",
     "cannot open {notvideo.avi}: not a video or image sequence OpenCV can decode"),
    (["live", "--camera", "99", "--rig", "default", "--dense", "-o"], "log.csv",
     "cannot open camera 99: no such camera, or another program is using it"),
    (["simulate", "fig9:distance_mm", "-o"], "s.png", "fig9: distance_mm needs a value: distance_mm=<number>"),
    (["track", "weld_seam:radius_mm", "--rig", "default", "-o"], "run/",
     "weld_seam: radius_mm needs a value: radius_mm=<number>"),
    (["design", "--rig", "{huge_focal.toml}", "-o"], "mirrors.json", "psvs design: error: "),
])
def test_known_failures_are_one_line_exit_2(capfd, files, earlier, argv, output, expected):
    subst = {p.name: str(p) for p in files.iterdir()}
    def fill(text):
        for name, path in subst.items():
            text = text.replace("{" + name + "}", path)
        return text
    if output.endswith("/"):    # a command writing into a folder: one earlier file in it
        out_path = earlier(output.rstrip("/")).parent / output.rstrip("/")
        out_path.unlink()
        out_path.mkdir()
        kept = earlier(f"{output}report.json")
    else:
        out_path = kept = earlier(output)
    code, _, err = run(capfd, *map(fill, argv), out_path)
    one_line(code, err, 2, fill(expected))
    assert "libpng error" not in err.replace("(libpng error: ", "")   # libpng's own line never shows
    assert kept.read_text() == EARLIER


def test_files_with_a_byte_order_mark_are_read(capfd, files):
    code, out, err = run(capfd, "triangulate", "--rig", files / "bom.toml", files / "bom.csv")
    assert code == 0 and err == "", err
    assert out.splitlines()[0] == "X_mm,Y_mm,Z_mm,Z_sigma_mm,valid" and len(out.splitlines()) == 2
    assert out.splitlines()[1].endswith(",1")          # the examples' first pair (450 mm) read whole


@pytest.fixture
def failing_design(monkeypatch):
    """``psvs design`` with a fault inside: its analysis raises ``exc``."""
    import psvs.cli.design_cmd
    def install(exc):
        def fail(*args, **kwargs):
            raise exc
        monkeypatch.setattr(psvs.cli.design_cmd, "design_mirrors", fail)
    return install


def test_an_internal_error_is_one_line_exit_1(capfd, earlier, failing_design, monkeypatch):
    monkeypatch.delenv("PSVS_DEBUG", raising=False)
    failing_design(ZeroDivisionError("division by zero"))
    out = earlier("mirrors.json")
    code, _, err = run(capfd, "design", "--rig", EXAMPLE, "-o", out)
    assert code == 1
    assert err == ("psvs design: internal error: ZeroDivisionError: division by zero "
                   "(PSVS_DEBUG=1 shows the traceback)\n")
    assert out.read_text() == EARLIER
    failing_design(MemoryError())
    code, _, err = run(capfd, "design", "--rig", EXAMPLE, "-o", out)
    assert (code, err) == (1, "psvs design: internal error: MemoryError (PSVS_DEBUG=1 shows the traceback)\n")
    failing_design(RuntimeError("first line\nsecond line"))
    code, _, err = run(capfd, "design", "--rig", EXAMPLE)
    one_line(code, err, 1, "internal error: RuntimeError: first line (PSVS_DEBUG")


def test_psvs_debug_shows_the_traceback(failing_design, monkeypatch):
    monkeypatch.setenv("PSVS_DEBUG", "1")
    failing_design(ZeroDivisionError("division by zero"))
    with pytest.raises(ZeroDivisionError):
        main(["design", "--rig", EXAMPLE])
    monkeypatch.setenv("PSVS_DEBUG", "0")     # 0 is off
    assert main(["design", "--rig", EXAMPLE]) == 1


def test_known_classes_and_interrupts_keep_their_status(capfd, failing_design):
    from psvs.errors import MeasurementError
    for exc, status, line in ((MeasurementError("too few points"), 1, "psvs design: cannot measure: too few points"),
                              (ValueError("bad"), 2, "psvs design: error: bad"),
                              (KeyboardInterrupt(), 130, "psvs design: interrupted")):
        failing_design(exc)
        code, _, err = run(capfd, "design", "--rig", EXAMPLE)
        assert (code, err.strip()) == (status, line)


def test_a_closed_pipe_ends_quietly(capsys, failing_design):
    failing_design(BrokenPipeError(32, "Broken pipe"))
    assert main(["design", "--rig", EXAMPLE]) == 141
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("level", [0, 90])
def test_a_constant_image_is_one_line_exit_1_and_nothing_written(capfd, tmp_path, level):
    """Issue 41: a black image gave exit 0 and an all-NaN map. Nothing to match is a measurement that cannot
    be made: exit 1, one line, no file (an older one kept)."""
    flat = tmp_path / "flat.png"
    write_png(flat, np.full((40, 60), level, np.uint8))
    out = tmp_path / "d.npy"
    out.write_bytes(b"an older map")
    code, _, err = run(capfd, "disparity", flat, "--min-disparity", "0", "--max-disparity", "20", "-o", out)
    assert (code, err) == (1, f"psvs disparity: cannot measure: the complex image is constant (every pixel {level}): "
                              "no texture to match\n")
    assert out.read_bytes() == b"an older map"


def _warn_from_outside_psvs():
    warnings.warn("a library's own warning", UserWarning, stacklevel=1)


def test_only_psvs_warnings_are_printed(capfd):
    """numpy's floating-point warnings (in this thread and in worker threads, which do not inherit its error
    state), numpy's own warnings.warn and another module's warnings are silent; psvs's are one line."""
    from psvs.dense import dense_disparity
    with quiet_libraries("psvs test"):
        np.array([1e308]) * 10.0
        np.array([0.0]) / 0.0
        np.mean(np.array([]))                   # numpy's "Mean of empty slice" (warnings.warn in numpy)
        with ThreadPoolExecutor(1) as ex:
            ex.submit(lambda: np.array([1e308]) * 10.0).result()
        _warn_from_outside_psvs()
        dense_disparity(np.full((20, 30), 5, np.uint8), 0.0, 4.0)
    assert capfd.readouterr().err == (
        "psvs test: warning: complex image is constant: no texture to match, disparity is all NaN\n")


def test_opencv_log_level_is_restored(capfd):
    import cv2
    log = cv2.utils.logging
    before = log.getLogLevel()
    with quiet_libraries("psvs test"):
        assert log.getLogLevel() == log.LOG_LEVEL_SILENT
    assert log.getLogLevel() == before


def _psvs(*argv, cwd):
    env = {k: v for k, v in os.environ.items() if k not in ("PSVS_DEBUG", "OPENCV_LOG_LEVEL", "OPENCV_FFMPEG_LOGLEVEL")}
    env["PYTHONPATH"] = str(ROOT / "src") + os.pathsep + env.get("PYTHONPATH", "")
    return subprocess.run([sys.executable, "-m", "psvs", *map(str, argv)], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=300)


def test_a_fresh_process_prints_no_library_lines(tmp_path):
    """As a user runs psvs: OpenCV loads after the command line silenced it (no "[ WARN:0@...] ... can't
    open camera by index"), and FFmpeg says nothing of a video cut short ("[ffv1 @ 0x...] ...")."""
    r = _psvs("live", "--camera", "99", "--rig", "default", "--dense", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr == (
        "psvs live: error: cannot open camera 99: no such camera, or another program is using it\n"), r.stderr
    from psvs.io.video import write_video
    rng = np.random.default_rng(1)
    write_video(tmp_path / "v.avi", [rng.integers(0, 256, (480, 640)).astype(np.uint8) for _ in range(5)])
    data = (tmp_path / "v.avi").read_bytes()
    (tmp_path / "cut.avi").write_bytes(data[: len(data) // 2])
    r = _psvs("live", "--video", "cut.avi", "--rig", "default", "--seed", "320,240", "--quiet", cwd=tmp_path)
    # psvs's lines, exit 1: the file is cut short (frames kept), and noise holds no twin; nothing else reaches
    # the terminal
    lines = r.stderr.splitlines()
    assert r.returncode == 1 and len(lines) == 2, r.stderr
    assert lines[0].startswith("psvs live: cut.avi ends after ") and "frames its header declares" in lines[0]
    assert lines[1].startswith("psvs live: cannot measure: the edge was never found: "
                               "no twin beyond chance in the frame"), r.stderr
