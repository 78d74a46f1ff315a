"""The Basler pylon source (psvs[basler]) on pylon's own camera emulator (PYLON_CAMEMU), the real pypylon code
path, serving psvs's simulated complex images from a folder (TestImageSelector=Off, ImageFileMode=On,
ImageFilename=DIR, set through --camera-set). The emulator reads a 16-bit file as full scale: a Mono12 frame
is the file's value >> 4, so a 12-bit frame v is served from a file holding v << 4."""
import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

os.environ.setdefault("PYLON_CAMEMU", "1")       # before pypylon is first imported (psvs imports it lazily)

from psvs.cli.main import main  # noqa: E402
from psvs.io.params import load_rig  # noqa: E402
from psvs.live.camera import Acquisition  # noqa: E402
from tests.support.mcap import read_mcap  # noqa: E402
from tests.support.video import FRAMES, write_frames

ROOT = Path(__file__).resolve().parents[2]


def serve(folder, size=None) -> list[str]:
    """--camera-set options serving ``folder``; ``size`` (W, H): the camera's region of interest (the
    emulator's default, 1024x1040, crops a larger image)."""
    roi = [] if size is None else ["--camera-set", f"Width={size[0]}", "--camera-set", f"Height={size[1]}"]
    return roi + ["--camera-set", "TestImageSelector=Off", "--camera-set", "ImageFileMode=On",
            "--camera-set", f"ImageFilename={folder}"]


EDGE = ("frame", "tracked", "seed_u", "seed_v", "n_pairs", "disparity_px", "depth_mm")


@pytest.mark.parametrize("rig_name, fmt", [
    ("default", "Mono8"), ("default", "Mono12"),
    pytest.param("mv1440", "Mono12", marks=pytest.mark.slow), pytest.param("mv1440", "Mono8", marks=pytest.mark.slow)])
def test_the_emulated_camera_tracks_exactly_as_the_video(rig_name, fmt, tmp_path, capsys):
    """`psvs live --camera basler:0` on the emulator serving the frames gives the same tracked edge and depths,
    digit for digit, as `psvs live --video` on the same frames; the MCAP's frame counters and timestamps rise
    strictly, on the host's clock (the emulator's timestamps are 0), none dropped; the settings are recorded."""
    video, served, seed = write_frames(tmp_path, rig_name, 8 if fmt == "Mono8" else 12)
    common = ["--rig", rig_name, "--seed", seed, "--quiet", "--max-frames", str(FRAMES)]
    assert main(["live", "--video", str(video), "-o", str(tmp_path / "v.csv"), *common]) == 0
    assert main(["live", "--camera", "basler:0", "--pixel-format", fmt, "--trigger", "software",
                 *serve(served, load_rig(rig_name).camera.image_size_px), "-o", str(tmp_path / "c.csv"),
                 "--mcap", str(tmp_path / "c.mcap"), *common]) == 0
    out = capsys.readouterr().out
    assert "basler:0815-0000 (Basler Emulation" in out and "0 frames dropped (frame counters 0-4)" in out
    v_rows, c_rows = (list(csv.DictReader((tmp_path / n).open())) for n in ("v.csv", "c.csv"))
    assert len(v_rows) == len(c_rows) == FRAMES and all(r["tracked"] == "1" for r in c_rows)
    assert [[r[k] for k in EDGE] for r in c_rows] == [[r[k] for k in EDGE] for r in v_rows]
    z = np.array([float(r["depth_mm"]) for r in c_rows])
    assert np.abs(z - (700 + np.array([0, 25, 50, 25, 0]))).max() < 0.01 * 700    # and right: 1 % of 700 mm
    _, _, msgs = read_mcap(tmp_path / "c.mcap")
    frames = [json.loads(m.data) for _, c, m in msgs if c.topic == "/psvs/frame"]
    counters, stamps = [f["camera_frame"] for f in frames], [f["timestamp_s"] for f in frames]
    assert len(frames) == FRAMES and np.all(np.diff(counters) > 0) and np.all(np.diff(stamps) > 0)
    assert {f["clock"] for f in frames} == {"host"} and sum(f["dropped"] for f in frames) == 0
    assert [r["clock"] for r in c_rows] == ["host"] * FRAMES and [r["camera_frame"] for r in c_rows] == \
        [str(c) for c in counters]
    table = (tmp_path / "c.camera.toml").read_text()
    assert f'pixel_format = "{fmt}"' in table and 'trigger = "software"' in table and f"ImageFilename = \"{served}\"" \
        in table and "auto_exposure = false" in table
    assert f"PixelFormat\t{fmt}" in (tmp_path / "c.camera.pfs").read_text()


def _emulated(folder, **kw):
    from psvs.live.pylon import PylonSource
    src = PylonSource("0")
    src.open()
    src.configure(Acquisition(features=(("TestImageSelector", "Off"), ("ImageFileMode", "On"),
                                        ("ImageFilename", str(folder))), **kw))
    return src


def test_software_trigger_one_frame_per_trigger_and_a_dropped_frame_is_counted(tmp_path):
    """With the software trigger no frame comes until the next grab triggers one (the emulator runs at
    100 frames/s free); free running, a frame taken out from under psvs (retrieved behind its back) shows as a
    gap in the camera's counter and is counted as dropped."""
    _, served, _ = write_frames(tmp_path, "default", 8)
    files = [cv2.imread(str(p), cv2.IMREAD_UNCHANGED) for p in sorted(served.iterdir())]
    with _emulated(served, trigger="software", frame_rate_hz=100.0) as src:
        got = [src.grab() for _ in range(3)]
        assert [f.counter for f in got] == [0, 1, 2] and all(np.array_equal(f.image, files[k])
                                                             for k, f in enumerate(got))
        assert src._cam.GetGrabResultWaitObject().Wait(300) is False     # 0.3 s = 30 frame periods: none taken
        assert src.grab().counter == 3
    with _emulated(served) as src:
        a, b = src.grab(), src.grab()
        src._cam.RetrieveResult(2000).Release()            # the frame psvs never sees
        c = src.grab()
        assert (a.counter, b.counter, c.counter) == (0, 1, 3) and (a.dropped, b.dropped, c.dropped) == (0, 0, 1)
        assert np.array_equal(c.image, files[3])


def test_a_camera_closed_under_the_grabber_stops_the_run_cleanly(tmp_path, capsys, monkeypatch):
    """The device is closed after the third frame: the run stops, keeps the three frames' log lines and its
    MCAP, says which frame was the last, and exits 1."""
    from psvs.live.pylon import PylonSource
    video, served, seed = write_frames(tmp_path, "default", 8)
    grab = PylonSource.grab

    def grab_then_unplug(self):
        frame = grab(self)
        if frame.index == 2:
            self._cam.Close()
        return frame
    monkeypatch.setattr(PylonSource, "grab", grab_then_unplug)
    log, mcap = tmp_path / "c.csv", tmp_path / "c.mcap"
    assert main(["live", "--camera", "basler:0", "--rig", "default", "--seed", seed, *serve(served), "-o", str(log),
                 "--mcap", str(mcap), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "camera lost" in err and "the last frame was 2 (camera frame 2)" in err
    assert [r["frame"] for r in csv.DictReader(log.open())] == ["0", "1", "2"]
    _, counts, _ = read_mcap(mcap)
    assert counts["/psvs/frame"] == 3 and counts["/psvs/log"] == 1


@pytest.mark.parametrize("args, message", [
    (["--camera", "basler:12345678"], "no Basler camera with serial 12345678 is connected (found: 0815-0000"),
    (["--camera", "basler:0", "--pixel-format", "Mono12p"], "--pixel-format Mono12p: the camera has no such"),
    (["--camera", "basler:0", "--camera-set", "NoSuchFeature=1"], "the camera has no feature NoSuchFeature"),
    (["--camera", "basler:0", "--exposure-us", "1e9"], "--exposure-us 1e+09 is outside the camera's"),
    (["--camera", "basler:0", "--camera-settings", "missing.pfs"], "--camera-settings: file not found"),
    (["--video", "v.avi", "--exposure-us", "100"], "camera acquisition options need --camera"),
    (["--camera", "nikon:1"], "--camera must be an OpenCV index"),
])
def test_camera_faults_are_one_line_exit_2_nothing_written(args, message, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["live", "--rig", "default", "--seed", "300,200", *args, "-o", "c.csv", "--mcap", "c.mcap"]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_a_feature_file_is_loaded_and_the_rig_files_acquisition_table_applied(tmp_path, capsys):
    """--camera-settings loads a .pfs (as pylon Viewer saves it: here the one a run recorded); the rig file's
    [camera.acquisition] sets exposure and format; the command line overrides the table."""
    _, served, seed = write_frames(tmp_path, "default", 8)
    rig = tmp_path / "rig.toml"
    rig.write_text((ROOT / "src/psvs/rigs/default.toml").read_text()
                   + "\n[camera.acquisition]\nexposure_us = 1500.0\npixel_format = \"Mono12\"\ngain_db = 0.0\n"
                   "[camera.acquisition.features]\nTestImageSelector = \"Off\"\n"
                   f"ImageFileMode = \"On\"\nImageFilename = \"{served}\"\n")
    assert main(["live", "--camera", "basler:0", "--rig", str(rig), "--seed", seed, "--max-frames", "2", "--quiet",
                 "--exposure-us", "2500", "-o", str(tmp_path / "a.csv")]) == 0
    table = (tmp_path / "a.camera.toml").read_text()
    assert "exposure_us = 2500.0" in table and 'pixel_format = "Mono12"' in table
    pfs = tmp_path / "a.camera.pfs"
    assert main(["live", "--camera", "basler:0", "--rig", "default", "--seed", seed, "--max-frames", "2", "--quiet",
                 "--camera-settings", str(pfs), "-o", str(tmp_path / "b.csv")]) == 0
    table = (tmp_path / "b.camera.toml").read_text()
    assert "exposure_us = 2500.0" in table and 'pixel_format = "Mono12"' in table
    capsys.readouterr()


BLOCK_PYPYLON = ("import sys; sys.modules['pypylon'] = None; from psvs.cli.main import main; "
                 "sys.exit(main(sys.argv[1:]))")


def test_without_the_extra(tmp_path):
    """pypylon made unimportable in a fresh interpreter: --camera basler:0 exits 2 naming psvs[basler], nothing
    written; psvs cameras still lists what OpenCV opens and says how to install the extra."""
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    run = subprocess.run([sys.executable, "-c", BLOCK_PYPYLON, "live", "--camera", "basler:0", "--rig", "default",
                          "--seed", "300,200", "-o", "c.csv"], cwd=tmp_path, env=env, capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 2 and "pip install 'psvs[basler]'" in run.stderr, run.stderr
    assert len(run.stderr.strip().splitlines()) == 1 and list(tmp_path.iterdir()) == []
    run = subprocess.run([sys.executable, "-c", BLOCK_PYPYLON, "cameras"], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert "OpenCV" in run.stdout and "pip install 'psvs[basler]'" in run.stdout


def test_psvs_cameras_lists_the_emulated_camera(capsys):
    assert main(["cameras"]) == 0
    out = capsys.readouterr().out
    assert "Basler" in out and "Emulation" in out and "0815-0000" in out and "basler:0815-0000" in out
    assert "OpenCV" in out


def test_capture_keeps_its_views_when_the_camera_is_lost(tmp_path, capsys, monkeypatch):
    """psvs capture from the emulated camera serving a hand-held card (four poses held two frames each), the
    device closed under the grabber after frame 5: it stops, keeps the views saved with the camera's settings
    beside them, names the last frame and exits 1 saying what is missing."""
    from psvs.live.pylon import PylonSource
    from tests.support.video import write_hand_video
    video = write_hand_video(tmp_path, holds=4, seed=2, hold_frames=2, move_frames=0, shared=True)
    frames = tmp_path / "frames"
    frames.mkdir()
    cap = cv2.VideoCapture(str(video.path))
    k = 0
    while (got := cap.read())[0]:
        cv2.imwrite(str(frames / f"f{k:03d}.png"), cv2.cvtColor(got[1], cv2.COLOR_BGR2GRAY))
        k += 1
    cap.release()
    grab = PylonSource.grab

    def grab_then_unplug(self):
        frame = grab(self)
        if frame.index == 5:
            self._cam.Close()
        return frame
    monkeypatch.setattr(PylonSource, "grab", grab_then_unplug)
    out = tmp_path / "views"
    code = main(["capture", "--camera", "basler:0", "--trigger", "software", *serve(frames), "--target",
                 str(video.target), "--rig", "clear", "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 1 and "camera lost" in err and "the last frame was 5 (camera frame 5)" in err, err
    views = sorted(p.name for p in out.glob("view_*.png"))
    assert 1 <= len(views) <= 3 and (out / "camera.toml").is_file() and (out / "camera.pfs").is_file()
    assert f"(kept {len(views)} in {out})" in err
