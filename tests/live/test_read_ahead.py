"""A video file's next frame decodes on a thread while the caller works on this one (psvs.live.source.VideoSource):
the same frames in the same order as OpenCV's own reader gives them, a damaged frame raised by the read that
reaches it, and nothing another thread prints meanwhile lost to the decoder's caught output."""
import subprocess
import sys
import textwrap

import cv2
import numpy as np
import pytest

from psvs.io.video import DamagedVideo, write_video
from psvs.live.source import VideoSource


@pytest.fixture(scope="module")
def video(tmp_path_factory):
    """12 FFV1 frames of random texture, each frame's mean its own (the order can be read off the frames)."""
    rng = np.random.default_rng(3)
    frames = [np.clip(rng.normal(40 + 15 * k, 12, (96, 128)), 0, 255).astype(np.uint8) for k in range(12)]
    path = tmp_path_factory.mktemp("ahead") / "v.avi"
    assert write_video(path, frames, fps=30.0) == len(frames)
    return path


def _opencv_frames(path):
    cap = cv2.VideoCapture(str(path))
    out = []
    while True:
        ok, img = cap.read()
        if not ok:
            break
        out.append(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img)
    cap.release()
    return out


def test_the_frames_are_opencvs_in_order(video):
    truth = _opencv_frames(video)
    with VideoSource(video=str(video)) as src:
        frames = [src.grab() for _ in range(len(truth) + 1)]
    assert frames[-1] is None
    assert [f.index for f in frames[:-1]] == list(range(len(truth)))
    for f, t in zip(frames[:-1], truth, strict=True):
        np.testing.assert_array_equal(f.image, t)


def test_a_source_left_after_a_few_frames_closes_with_its_read_ahead(video):
    truth = _opencv_frames(video)
    src = VideoSource(video=str(video))
    got = [src.read() for _ in range(3)]        # the fourth frame is decoding when it is closed
    src.close()
    src.close()
    for g, t in zip(got, truth[:3], strict=True):
        np.testing.assert_array_equal(g, t)
    with pytest.raises(ValueError, match="is not open"):
        src.read()


def test_a_damaged_frame_read_ahead_is_raised_by_the_read_that_reaches_it(video, tmp_path):
    data = bytearray(video.read_bytes())
    cut = tmp_path / "cut.avi"
    cut.write_bytes(bytes(data[: int(len(data) * 0.6)]))     # the header still declares 12 frames
    with VideoSource(video=str(cut)) as src:
        kept = []
        with pytest.raises(DamagedVideo) as err:
            while (f := src.read()) is not None:
                kept.append(f)
    assert 2 <= len(kept) < 12
    assert f"{len(kept)} of the 12 frames" in str(err.value) or f"frame {len(kept)} of" in str(err.value)
    for g, t in zip(kept, _opencv_frames(video), strict=False):
        np.testing.assert_array_equal(g, t)


def test_lines_printed_while_frames_decode_all_reach_the_terminal(video):
    """Each frame's decode redirects descriptor 2 to catch the decoder's words; a line the caller prints on
    sys.stderr meanwhile must still arrive (before the read-ahead, the caller printed only between reads)."""
    code = textwrap.dedent(f"""
        import sys
        from psvs.live.source import VideoSource
        n = 0
        for _ in range(20):
            with VideoSource(video={str(video)!r}) as src:
                while src.read() is not None:
                    for k in range(30):
                        print(f"line {{n}}", file=sys.stderr)
                        n += 1
        print(n)
    """)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    n = int(proc.stdout.strip())
    assert n == 20 * 12 * 30
    assert proc.stderr.splitlines() == [f"line {k}" for k in range(n)]
