"""Rerun recordings (issue 44 item 4): what `psvs live`, `psvs disparity` (and `track`/`replay`,
tests/robot/test_drift.py) write with --rerun, read back with Rerun's own reader (tests/support/rerun.py) and
compared by value with what the same run wrote otherwise (its CSV log read with the csv module, its .npy maps,
the video decoded by OpenCV) and with closed forms (the virtual cameras of eqs. 1-8, the pinhole f/pitch); and
the served viewer in Chromium, drawing what psvs sends."""
import csv
import socket
import sys
import urllib.request

import cv2
import numpy as np
import pytest

from psvs.cli.main import main
from psvs.io.params import load_rig
from psvs.io.video import write_video
from psvs.live.dense import DenseSensor
from psvs.simulate.builtin import textured
from psvs.simulate.render import render
from tests.support.browser import shot
from tests.support.rerun import image_of, read_rrd
from tests.support.web import free_port


@pytest.fixture(scope="module")
def video(tmp_path_factory):
    rig = load_rig("default")
    frames = [render(textured(800.0 + 40 * k), rig, seed=k, supersample=1).image for k in range(4)]
    path = tmp_path_factory.mktemp("rerun") / "textured.avi"
    write_video(path, frames, 30.0)
    return path


def _decoded(path) -> list[np.ndarray]:
    cap, out = cv2.VideoCapture(str(path)), []
    while (got := cap.read())[0]:
        out.append(cv2.cvtColor(got[1], cv2.COLOR_BGR2GRAY))
    return out


def test_live_records_every_frames_depth(video, tmp_path, capsys):
    """Every frame: the complex image (the video's, pixel for pixel) under the camera's pinhole, its dense depth
    map (its median the log's), its points, its disparity map where the answer holds (NaN where not supported),
    and on the frames the echo test ran on the separated views; the rig's O, O1, O2 where eqs. 1-8 put them;
    the self-check's record; the file replaced only whole."""
    log, rrd = tmp_path / "live.csv", tmp_path / "live.rrd"
    assert main(["live", "--video", str(video), "--rig", "default", "--dense", "--fast", "--quiet", "-o", str(log),
                 "--rerun", str(rrd)]) == 0
    capsys.readouterr()
    got = read_rrd(rrd)
    with log.open() as f:
        rows = list(csv.DictReader(f))
    frames = _decoded(video)
    images = [image_of(r) for r in got["/psvs_optical_frame/camera/image"]]
    assert len(images) == len(rows) == len(frames) == 4
    for a, b in zip(images, frames, strict=True):
        np.testing.assert_array_equal(a, b)
    depth = got["/maps/dense_depth"]
    assert [r["time"] for r in depth] == pytest.approx([float(r["timestamp_s"]) for r in rows], abs=1e-6)
    for r, row in zip(depth, rows, strict=True):
        z = image_of(r, "DepthImage")
        assert r["DepthImage:meter"] == [1000.0]       # mm (the map on the dense grid: --fast, a stride)
        assert float(np.nanmedian(z)) == pytest.approx(float(row["dense_median_z_mm"]), abs=1e-3)
    assert len(got["/psvs_optical_frame/dense_points"]) == 4
    # the disparity map where each frame's answer holds, and the views of the frames the echo test ran on, by
    # value against the library's dense sensor run again on the decoded frames
    sensor = DenseSensor(load_rig("default"))
    again = [(sensor.step(f), sensor.views()) for f in frames]
    maps = got["/maps/dense_disparity"]
    assert len(maps) == 4 and all(r["DepthImage:meter"] == [1.0] for r in maps)
    for r, (d, _) in zip(maps, again, strict=True):
        np.testing.assert_array_equal(image_of(r, "DepthImage"), np.where(d.held, d.disparity_px, np.nan))
        # the objects at least (the wall behind them leaves the 400-1200 mm range at the third frame, 1232 mm,
        # and is held no more: psvs.live.dense)
        assert np.isfinite(image_of(r, "DepthImage")).mean() > 0.15
    tested = [k for k, (d, _) in enumerate(again) if d.tested]
    assert tested[0] == 0 and [r["time"] for r in got["/views/left"]] == pytest.approx(
        [float(rows[k]["timestamp_s"]) for k in tested], abs=1e-6)
    for view, i in (("left", 0), ("right", 1)):
        for r, k in zip(got[f"/views/{view}"], tested, strict=True):
            np.testing.assert_array_equal(image_of(r), again[k][1][i].astype(np.float32))
    # the rig: the camera at O, the virtual cameras at (-+b/2, 0, -b/2) (the ideal rig, b = 100 mm)
    centres = got["/psvs_optical_frame/rig/centres"][0]
    np.testing.assert_allclose(centres["Points3D:positions"], [[0, 0, 0], [-50, 0, -50], [50, 0, -50]], atol=1e-9)
    assert centres["Points3D:labels"] == ["O", "O1", "O2"]
    pin = np.array(got["/psvs_optical_frame/camera"][0]["Pinhole:image_from_camera"][0]).reshape(3, 3).T
    cam = load_rig("default").camera
    np.testing.assert_allclose(pin, [[cam.focal_length_mm / cam.pixel_pitch_mm[0], 0, cam.principal_point_px[0] + 0.5],
                                     [0, cam.focal_length_mm / cam.pixel_pitch_mm[1], cam.principal_point_px[1] + 0.5],
                                     [0, 0, 1]], atol=1e-6)
    assert len(got["/psvs_optical_frame/rig/glasses"][0]["LineStrips3D:strips"]) == 4
    assert [r["Scalars:scalars"][0] for r in got["/records/frame/frame"]] == [0.0, 1.0, 2.0, 3.0]
    assert not list(tmp_path.glob(".*.tmp"))


def test_disparity_interrupted_while_recording_keeps_the_earlier_results(video, tmp_path, capsys, monkeypatch):
    """Ctrl-C while the recording is written: the earlier complete recording and maps stay as they were, no
    temporary file is left (trial 48: the .rrd had been replaced by the rig and the image alone, the maps
    written)."""
    image = tmp_path / "frame.png"
    cv2.imwrite(str(image), _decoded(video)[0])
    d, rrd = tmp_path / "d.npy", tmp_path / "d.rrd"
    argv = ["disparity", str(image), "--rig", "default", "--fast", "-o", str(d), "--rerun", str(rrd)]
    assert main(argv) == 0
    capsys.readouterr()
    before = {p.name: p.read_bytes() for p in (d, rrd)}
    from psvs.io.rerun_sink import RerunSink

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(RerunSink, "disparity", interrupted)
    assert main([*argv[:2], "--rig", "default", "-o", str(d), "--rerun", str(rrd)]) == 130   # default mode
    assert "interrupted" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in (d, rrd)} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.npy", "d.rrd", "frame.png"]


def test_disparity_records_its_maps_views_and_cloud(video, tmp_path, capsys):
    """One complex image: its maps equal the .npy files written beside, the depth the --depth map at the trusted
    pixels (NaN elsewhere: the recorded cloud's, as --cloud's), the views the complex image's size on the ideal
    rig, the points as many as that depth's finite pixels."""
    image = tmp_path / "frame.png"
    cv2.imwrite(str(image), _decoded(video)[0])
    out = {k: tmp_path / f"{k}.npy" for k in ("d", "r", "z", "c")}
    rrd = tmp_path / "d.rrd"
    assert main(["disparity", str(image), "--rig", "default", "--fast", "-o", str(out["d"]), "--right", str(out["r"]),
                 "--depth", str(out["z"]), "--confidence", str(out["c"]), "--rerun", str(rrd)]) == 0
    capsys.readouterr()
    got = read_rrd(rrd)
    np.testing.assert_array_equal(image_of(got["/maps/disparity_left"][0], "DepthImage"), np.load(out["d"]))
    np.testing.assert_array_equal(image_of(got["/maps/disparity_right"][0], "DepthImage"), np.load(out["r"]))
    z = np.where(np.load(out["c"]) > 0, np.load(out["z"]), np.nan)
    assert 0.3 * z.size < np.isfinite(z).sum() < np.isfinite(np.load(out["z"])).sum()
    np.testing.assert_array_equal(image_of(got["/maps/depth"][0], "DepthImage"), z)
    assert len(got["/psvs_optical_frame/dense_points"][0]["Points3D:positions"]) == int(np.isfinite(z).sum())
    for view in ("left", "right"):
        assert image_of(got[f"/views/{view}"][0]).shape == (480, 640)
    np.testing.assert_array_equal(image_of(got["/psvs_optical_frame/camera/image"][0]), cv2.imread(str(image), 0))


@pytest.mark.parametrize("args, said", [
    (["--rerun", "out.txt"], "must end in .rrd"),
    (["--rerun", "no/such/dir/x.rrd"], "output folder does not exist"),
    (["--rerun-serve", "80"], "--rerun-serve must be a port in 1024..65534"),
])
def test_bad_rerun_arguments_are_one_line_exit_2(video, tmp_path, monkeypatch, capsys, args, said):
    monkeypatch.chdir(tmp_path)
    assert main(["live", "--video", str(video), "--rig", "default", "--dense", "--fast", *args]) == 2
    err = capsys.readouterr().err
    assert said in err and len(err.strip().splitlines()) == 1


def test_without_the_rerun_package_the_option_says_what_to_install(video, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "rerun", None)          # as if rerun-sdk were not installed
    assert main(["live", "--video", str(video), "--rig", "default", "--rerun", str(tmp_path / "x.rrd")]) == 2
    assert "--rerun needs the rerun-sdk package: pip install 'psvs[rerun]'" in capsys.readouterr().err
    assert not (tmp_path / "x.rrd").exists()


def test_the_viewer_is_served_on_the_loopback_and_a_taken_port_is_one_line():
    """--rerun-serve's sink: Rerun's own web viewer (from the wheel, offline) on the port, the data on the next."""
    from psvs.io.rerun_sink import RerunSink
    port = free_port()
    with RerunSink(None, port) as sink:
        assert sink.url.startswith(f"http://127.0.0.1:{port}/?url=rerun+http://127.0.0.1:{port + 1}/")
        html = urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=10).read().decode()
        assert "Rerun" in html and "<html" in html.lower()
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        busy = taken.getsockname()[1]
        with pytest.raises(OSError, match=f"cannot serve Rerun's viewer on ports {busy - 1} and {busy}") as exc:
            RerunSink(None, busy - 1)
        assert "\n" not in str(exc.value)


def _dark_px(png: bytes) -> int:
    """How many pixels of a screenshot are all but black (grey <= 12)."""
    grey = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_GRAYSCALE)
    return int(np.count_nonzero(grey <= 12))


def test_the_served_viewer_draws_what_psvs_sends_in_a_browser(webgl_page):
    """--rerun-serve as a user opens it: Rerun's web viewer (the wheel's, offline; WebGL on the CPU) in
    Chromium at the URL psvs prints, fed over the loopback, draws the complex image psvs logs: a black frame
    of 320 x 240 px appears as a black area of the page, none before (the viewer's own pixels are light)."""
    from psvs.io.rerun_sink import RerunSink
    port = free_port()
    with RerunSink(None, port) as sink:
        webgl_page.goto(sink.url)
        webgl_page.wait_for_timeout(3000)
        before = _dark_px(webgl_page.screenshot())
        sink.rig(load_rig("default"))
        for k in range(3):
            sink.image(0.1 * k, np.zeros((240, 320), np.uint8))
        dark = before
        for _ in range(60):                       # the WASM viewer loads and draws in a few seconds
            webgl_page.wait_for_timeout(1000)
            dark = _dark_px(webgl_page.screenshot())
            if dark > before + 20000:
                break
        shot(webgl_page, "rerun_viewer.png")
    assert before < 5000 and dark > before + 20000, (before, dark)
