"""Image sequence patterns (psvs.live.source.check_pattern): one frame number of at most 12 digits, or a
one-line refusal naming the problem (issue 41: `%999999999d` produced a one-gigabyte error line)."""
import numpy as np
import pytest

from psvs.io.images import write_png
from psvs.live.source import check_pattern, sequence_files
from tests.support.cli import run


def test_a_pattern_reads_its_frames_in_order_from_the_first_that_exists(tmp_path):
    for k in (3, 4, 5):
        write_png(tmp_path / f"a%b_{k:04d}.png", np.full((4, 6), k, np.uint8))
    write_png(tmp_path / "a%b_7.png", np.zeros((4, 6), np.uint8))        # not of the pattern: %04d writes 0007
    write_png(tmp_path / "a%b_00070.png", np.zeros((4, 6), np.uint8))    # nor this (0070)
    files = sequence_files(str(tmp_path / "a%%b_%04d.png"))
    assert [f.name for f in files] == ["a%b_0003.png", "a%b_0004.png", "a%b_0005.png"]
    assert check_pattern("seq_%d.png") and check_pattern("seq_%012d.png") and not check_pattern("seq.png")


@pytest.mark.parametrize("pattern, later", [("q_%03d.png", ("q_010.png", "q_011.png")), ("q_%d.png", ("q_1000.png",))])
def test_a_sequence_with_a_gap_is_refused_not_cut_at_it(capsys, tmp_path, pattern, later):
    """Trial 45: q_005..007 then q_010, q_011: the batch read 3 frames, said "3 ok", exit 0, and never read the
    rest. Frames of the pattern after a missing one: exit 2, one line naming the gap, nothing written."""
    for k in (5, 6, 7):
        write_png(tmp_path / (pattern % k), np.full((4, 6), k, np.uint8))
    for name in later:
        write_png(tmp_path / name, np.zeros((4, 6), np.uint8))
    with pytest.raises(ValueError, match=f"{pattern % 8} is missing, yet {len(later)} frame"):
        sequence_files(str(tmp_path / pattern))
    code, _, err = run(capsys, "batch", "disparity", str(tmp_path / pattern), "--rig", "default", "-o",
                       str(tmp_path / "out"))
    assert code == 2 and len(err.strip().splitlines()) == 1 and f"(from {later[0]})" in err, err
    assert not (tmp_path / "out").exists()


def test_a_folder_sequence_holds_every_format_psvs_reads(tmp_path):
    """A folder of frames in each format the README lists (PNM and PPM were left out), read in name order
    with their values; a text file is not a frame."""
    import cv2

    from psvs.io.images import IMAGE_SUFFIXES, read_grey
    for k, suffix in enumerate(IMAGE_SUFFIXES):
        ok, buf = cv2.imencode(".pgm" if suffix == ".pnm" else suffix,
                               cv2.cvtColor(np.full((4, 6), 40 + k, np.uint8), cv2.COLOR_GRAY2BGR)
                               if suffix == ".ppm" else np.full((4, 6), 40 + k, np.uint8))
        assert ok, suffix
        (tmp_path / f"f{k:02d}{suffix}").write_bytes(buf.tobytes())
    (tmp_path / "notes.txt").write_text("not a frame")
    files = sequence_files(str(tmp_path))
    assert [f.name for f in files] == [f"f{k:02d}{s}" for k, s in enumerate(IMAGE_SUFFIXES)]
    lossless = [k for k, s in enumerate(IMAGE_SUFFIXES) if s not in (".jpg", ".jpeg")]
    assert [int(read_grey(files[k]).mean()) for k in lossless] == [40 + k for k in lossless]


@pytest.mark.parametrize("pattern, message", [
    ("seq_%999999999d.png", "a frame number of 999999999 digits; at most 12"),
    ("seq_%013d.png", "a frame number of 13 digits; at most 12"),
    ("seq_%s_%d.png", "give one frame number, %d or %0Nd"),
    ("seq_%d_%d.png", "give one frame number, %d or %0Nd"),
    ("seq_%5.2f.png", "give one frame number, %d or %0Nd"),
])
def test_a_pattern_that_is_not_one_frame_number_is_one_short_line(capsys, tmp_path, pattern, message):
    code, _, err = run(capsys, "batch", "disparity", str(tmp_path / pattern), "--rig", "default", "-o",
                       str(tmp_path / "out"))
    assert code == 2 and len(err.strip().splitlines()) == 1 and len(err) < 300 and message in err, err
    assert not (tmp_path / "out").exists()


def test_a_frame_of_another_size_stops_the_run_and_keeps_the_frames_before_it(tmp_path, capsys):
    """A sequence whose second frame is another camera's (an adversarial trial: exit 2 after frame 0, the frame
    not named, the log not written): as a damaged frame, the run stops there, names it, keeps frame 0 in its log
    (the csv module reads it back) and exits 1; the odd frame first is bad input, exit 2."""
    import csv

    from psvs.io.params import load_rig
    from psvs.simulate.builtin import fig5a
    from psvs.simulate.render import render
    small = render(fig5a(), load_rig("default"), supersample=1, seed=1).image
    seq = tmp_path / "seq"
    seq.mkdir()
    for k, img in enumerate((small, np.zeros((1080, 1440), np.uint8), small)):
        write_png(seq / f"s_{k:03d}.png", img)
    log = tmp_path / "log.csv"
    code, out, err = run(capsys, "live", "--video", str(seq), "--rig", "default", "--seed", "540,330", "-o", str(log))
    assert code == 1 and "frame 0: Z " in out
    assert "psvs live: frame 1 is 1440x1080 px but the rig's camera is 640x480 px; frames 0-0 are kept" in err
    with log.open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 1 and rows[0]["frame"] == "0"
    (seq / "s_000.png").unlink()
    code, _, err = run(capsys, "live", "--video", str(seq), "--rig", "default", "--seed", "540,330", "-o", str(log))
    assert code == 2 and err.count("\n") == 1 and "1440x1080 px but the rig's camera is 640x480 px" in err
