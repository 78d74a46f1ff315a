"""A damaged video frame is refused, not measured (adversarial trial: an FFV1 file with zeroed bytes was read as
the last good frame again, and `psvs live` and `psvs batch` measured it as new): the decoder's own complaint,
caught around each open and read (psvs.io.video.decoded), names the frame."""
import numpy as np
import pytest

from psvs.cli.main import main
from psvs.io.video import DamagedVideo, read_video_frame, video_frames, write_video
from psvs.live.source import open_video

FRAMES = 6


@pytest.fixture(scope="module")
def videos(tmp_path_factory):
    """An FFV1 video of 6 noise frames (the default rig's 640 x 480), and a copy with zeroed bytes from 60 %
    of the file on."""
    root = tmp_path_factory.mktemp("video")
    rng = np.random.default_rng(3)
    frames = [rng.integers(0, 256, (480, 640), dtype=np.uint8) for _ in range(FRAMES)]
    good = root / "good.avi"
    write_video(good, frames)
    data = bytearray(good.read_bytes())
    for i in range(int(0.6 * len(data)), len(data) - 2000, 3000):
        data[i:i + 40] = bytes(40)
    bad = root / "bad.avi"
    bad.write_bytes(bytes(data))
    cut = root / "cut.avi"                                  # truncated: the header still declares 6 frames
    cut.write_bytes(good.read_bytes()[:int(0.55 * len(data))])
    return frames, good, bad, cut


def test_an_intact_video_reads_every_frame_exactly(videos, capfd):
    frames, good, *_ = videos
    assert video_frames(good) == (FRAMES, (640, 480))
    for k in (0, 3, FRAMES - 1):
        assert np.array_equal(read_video_frame(good, k), frames[k])
    with open_video(str(good)) as src:
        got = list(src)
    assert len(got) == FRAMES and all(np.array_equal(a, b) for a, b in zip(got, frames, strict=True))
    assert capfd.readouterr().err == ""


def test_a_damaged_frame_is_named_and_the_frames_before_it_read(videos, capfd):
    frames, _, bad, _ = videos
    with open_video(str(bad)) as src, pytest.raises(ValueError, match=r"frame (\d) of .*bad\.avi is damaged: the "
                                                                      r"decoder said \"slice CRC mismatch") as exc:
        got = []
        for img in src:
            got.append(img)
    first_bad = int(exc.value.args[0].split()[1])
    assert 0 < first_bad < FRAMES and len(got) == first_bad
    assert all(np.array_equal(a, b) for a, b in zip(got, frames, strict=False))   # what was read is right
    with pytest.raises(ValueError, match="is damaged"):
        read_video_frame(bad, FRAMES - 1)
    assert np.array_equal(read_video_frame(bad, 0), frames[0])
    assert capfd.readouterr().err == ""                  # the decoder's words caught, not on the terminal


def test_batch_refuses_the_damaged_frames_and_keeps_the_good_ones(videos, tmp_path, capfd):
    import pyarrow.parquet as pq
    _, _, bad, _ = videos
    out = tmp_path / "out"
    rc = main(["batch", "disparity", str(bad), "--rig", "default", "-o", str(out), "--workers", "1"])
    status = pq.read_table(out / "results.parquet").to_pydict()["status"]
    err = capfd.readouterr().err
    assert rc != 0                          # no frame measured: damaged ones bad input, noise ones refused
    assert len(status) == FRAMES and 1 <= status.count("bad input") < FRAMES, status
    assert "cannot measure" in status and "ok" not in status
    assert "[ffv1" not in err                # the decoder's own lines caught


def test_a_truncated_video_is_not_read_as_a_shorter_one(videos, capfd):
    """Its header declares 6 frames; the file ends after some: the frames before are read exactly, then
    DamagedVideo says how many of the declared ones came (it ended the stream in silence)."""
    frames, _, _, cut = videos
    with open_video(str(cut)) as src, pytest.raises(DamagedVideo, match=r"cut\.avi ends after (\d) of the 6 "
                                                                        "frames its header declares") as exc:
        got = []
        for img in src:
            got.append(img)
    n = int(exc.value.args[0].split(" ends after ")[1].split()[0])
    assert 0 < n < FRAMES and len(got) == n
    assert all(np.array_equal(a, b) for a, b in zip(got, frames, strict=False))
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize("which", ["bad", "cut"])
def test_live_stops_at_the_damage_keeps_the_frames_before_and_exits_1(videos, tmp_path, capfd, which):
    """psvs live on a damaged or truncated video: exit 1, one line naming the file and the frames kept (the
    self-check's verdict on the noise besides), the log holding one row per frame read (it exited 0 on a
    truncated file, and lost the log on a damaged one)."""
    import csv
    _, _, bad, cut = videos
    log = tmp_path / "live.csv"
    rc = main(["live", "--video", str(bad if which == "bad" else cut), "--rig", "default", "--seed", "320,240",
               "-o", str(log), "--quiet"])
    err = [line for line in capfd.readouterr().err.splitlines() if "frames 0-" in line]   # (and the self-check's)
    assert rc == 1 and len(err) == 1, err
    n = int(err[0].split("frames 0-")[1].split()[0]) + 1
    assert 0 < n < FRAMES and ("is damaged" in err[0] or "ends after" in err[0]), err
    with open(log, newline="") as f:
        assert [int(r["frame"]) for r in csv.DictReader(f)] == list(range(n))
