import numpy as np
import pytest

from psvs.io.images import read_grey
from psvs.io.params import save_rig
from tests.support.cli import run


@pytest.fixture
def small_rig_file(tmp_path):
    from psvs import default_rig
    rig = default_rig().replace(pixel_pitch_mm=(0.04, 0.04), image_size_px=(160, 120), principal_point_px=(79.5, 59.5))
    path = tmp_path / "small.toml"
    save_rig(rig, path)
    return str(path)


def test_list(capsys):
    code, out, _ = run(capsys, "simulate", "--list")
    assert code == 0 and "fig5b" in out and "weld_seam" in out and "parameters:" in out


def test_render_with_truth(capsys, tmp_path, small_rig_file):
    out, truth = tmp_path / "f9.png", tmp_path / "f9.npz"
    code, _, err = run(capsys, "simulate", "fig9:distance_mm=700", "--rig", small_rig_file, "-o", str(out),
                       "--truth", str(truth), "--seed", "3", "--supersample", "1")
    assert code == 0 and "160x120" in err
    img = read_grey(out)
    assert img.shape == (120, 160)
    t = np.load(truth)
    assert set(t.files) >= {"left", "right", "depth_left_mm", "disparity_left_px", "valid_left", "valid_right"}
    assert np.nanmin(t["depth_left_mm"]) == pytest.approx(700.0, abs=20)


def test_same_seed_same_image(capsys, tmp_path, small_rig_file):
    paths = [tmp_path / f"{i}.png" for i in range(3)]
    for p, seed in zip(paths, ("1", "1", "2"), strict=True):
        assert run(capsys, "simulate", "fig5a", "--rig", small_rig_file, "-o", str(p), "--seed", seed,
                   "--supersample", "1")[0] == 0
    a, b, c = (read_grey(p) for p in paths)
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_sequence(capsys, tmp_path, small_rig_file):
    out = tmp_path / "seq.png"
    code, _, _ = run(capsys, "simulate", "fig5b", "--rig", small_rig_file, "-o", str(out), "--frames", "3",
                     "--move-mm", "0,0,-20", "--supersample", "1")
    assert code == 0
    assert sorted(p.name for p in tmp_path.glob("seq_*.png")) == ["seq_000.png", "seq_001.png", "seq_002.png"]


def test_a_sequence_refused_part_way_says_what_it_did(capsys, tmp_path, small_rig_file):
    """Trial 31: a sequence whose third frame is refused (the rig moved into the pattern) printed the first two
    frames' lines as if written, then removed them; trial 43: it was refused only after rendering two frames.
    Now every pose is checked before any frame is rendered: the refusal, naming the frame, is the one line
    and nothing is written; a sequence that lands says which files it wrote (read back: the images the lines
    describe)."""
    out = tmp_path / "a.png"
    argv = ("simulate", "fig9", "--rig", small_rig_file, "-o", str(out), "--frames", "3", "--supersample", "1")
    code, _, err = run(capsys, *argv, "--move-mm", "0,0,600")
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith("psvs simulate: error: frame 2 of 3: object ") and "is behind the rig" in err, err
    assert not list(tmp_path.glob("a_*.png"))
    code, _, err = run(capsys, *argv, "--move-mm", "0,0,100")
    lines = err.strip().splitlines()
    assert code == 0 and len(lines) == 4 and lines[-1] == "wrote a_000.png ... a_002.png: 3 frames", err
    for i, line in enumerate(lines[:3]):
        name = tmp_path / f"a_{i:03d}.png"
        assert line.startswith(f"frame {i} rendered ({name.name}): 160x120, mean grey ")
        assert float(line.rsplit(" ", 1)[1]) == pytest.approx(read_grey(name).mean(), abs=0.05)


@pytest.mark.parametrize("scene_text, args, message", [
    ('[[objects]]\ntype = "cone"\n', [], "unknown primitive 'cone'"),
    ('[[objects]]\ntype = "rectangle"\nsize_mm = [0, 5]\nposition_mm = [0, 0, 500]\n', [], "size_mm must be > 0 mm"),
    ('[[objects]]\ntype = "rectangle"\nsize_mm = [5, 5]\nposition_mm = [0, 0, 500]\n'
     'texture = { type = "image", file = "gone.png" }\n', [], "texture file not found"),
    ('[[objects]]\ntype = "rectangle"\nsize_mm = [5, 5]\nposition_mm = [0, 0, -100]\n', [], "is behind the rig"),
    ('[[objects]]\ntype = "sphere"\nradius_mm = 5\nposition_mm = [0, 0, 500]\n', ["--supersample", "0"],
     "supersample must be an integer >= 1"),
    ('[[objects]]\ntype = "sphere"\nradius_mm = 5\nposition_mm = [0, 0, 500]\n', ["--move-mm", "1,2"],
     "--move-mm must be 'dx,dy,dz'"),
    ('[[objects]]\ntype = "sphere"\nradius_mm = 5\nposition_mm = [0, 0, 500]\n', ["--move-mm", "nan,0,0"],
     "three finite numbers in mm, got 'nan,0,0'"),
    ('[[objects]]\ntype = "sphere"\nradius_mm = 5\nposition_mm = [0, 0, 500]\n', ["--seed", "-1"],
     "--seed must be >= 0, got -1"),
    # 160x120 px x 1000^2 samples x 300 B: ~5.4 TiB, refused before any allocation, naming the option
    ('[[objects]]\ntype = "sphere"\nradius_mm = 5\nposition_mm = [0, 0, 500]\n', ["--supersample", "1000"],
     "--supersample 1000 (160x120 px x 1000000 samples per pixel) needs about 5.2 TiB of memory"),
])
def test_bad_input_exits_2_and_keeps_output(capsys, tmp_path, small_rig_file, scene_text, args, message):
    scene = tmp_path / "scene.toml"
    scene.write_text(scene_text)
    out = tmp_path / "out.png"
    out.write_bytes(b"earlier image")
    code, _, err = run(capsys, "simulate", str(scene), "--rig", small_rig_file, "-o", str(out), *args)
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1
    assert out.read_bytes() == b"earlier image"


def test_unknown_scene_and_missing_output(capsys):
    code, _, err = run(capsys, "simulate", "fig99", "-o", "x.png")
    assert code == 2 and "neither a scene file nor a built-in" in err
    code, _, err = run(capsys, "simulate", "fig5a")
    assert code == 2 and "give a SCENE and -o OUT.png" in err


def test_sequence_as_lossless_video(capsys, tmp_path, small_rig_file):
    """-o OUT.avi with --frames: an FFV1 video whose frames are exactly the PNG sequence's."""
    from psvs.live.source import VideoSource
    args = ["fig5a", "--rig", small_rig_file, "--frames", "3", "--move-mm", "0,0,-30", "--supersample", "1"]
    assert run(capsys, "simulate", *args, "-o", str(tmp_path / "seq.png"))[0] == 0
    code, _, err = run(capsys, "simulate", *args, "-o", str(tmp_path / "seq.avi"), "--fps", "25")
    assert code == 0 and "seq.avi: 3 frames, FFV1, 25 frames/s" in err
    with VideoSource(video=str(tmp_path / "seq.avi")) as src:
        frames = list(src)
        assert src.fps == 25
    assert len(frames) == 3
    assert all(np.array_equal(f, read_grey(tmp_path / f"seq_{i:03d}.png")) for i, f in enumerate(frames))
    for fps in ("0", "0.001", "1e9"):       # trial 47: 1e9 written as 600 frames/s, 0.001 an FFmpeg error
        code, _, err = run(capsys, "simulate", *args, "-o", str(tmp_path / "bad.avi"), "--fps", fps)
        assert code == 2 and "--fps must be 0.1..1000 frames/s" in err and not (tmp_path / "bad.avi").exists()
        assert len(err.strip().splitlines()) == 1, err


def test_supersample_limit_follows_the_memory_available(capsys, tmp_path, small_rig_file, monkeypatch):
    """With 1 GiB available (80 % usable) at 160x120 px x 300 B per sample: K = floor(sqrt(0.8 GiB / 5.76 MB))
    = 12 fits, 13 does not; the message names the option, the need and the largest K that fits."""
    from psvs import _budget
    monkeypatch.setattr(_budget, "available_bytes", lambda: 1 << 30)
    out = tmp_path / "o.png"
    code, _, err = run(capsys, "simulate", "fig9", "--rig", small_rig_file, "-o", str(out), "--supersample", "13")
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "--supersample 13" in err and "more than the 819.2 MiB available; at most --supersample 12 fits" in err
    assert not out.exists()


def test_a_move_along_minus_x_is_a_value_not_an_option(capsys, tmp_path, small_rig_file):
    """Trial 44: ``--move-mm -150,0,0`` was taken for an option ("expected one argument"); a list of numbers
    that starts with a negative one is the option's value, as ``--move-mm=-150,0,0`` is, and the frames move."""
    from psvs.cli.main import negative_lists_joined
    assert negative_lists_joined(["simulate", "--move-mm", "-1.5e1,0,-.5", "--seed", "-5,10", "-o", "-x,1"]) == [
        "simulate", "--move-mm=-1.5e1,0,-.5", "--seed=-5,10", "-o", "-x,1"]
    assert negative_lists_joined(["--frames", "-3", "--move-mm=-1,0,0", "-q", "-1,2"]) == [
        "--frames", "-3", "--move-mm=-1,0,0", "-q", "-1,2"]
    outs = []
    for move in ("-20,0,0", "0,0,0"):
        out = tmp_path / f"m{move[0]}.png"
        code, _, err = run(capsys, "simulate", "fig5b", "--rig", small_rig_file, "-o", str(out), "--frames", "2",
                           "--move-mm", move, "--supersample", "1")
        assert code == 0, err
        outs.append([read_grey(out.with_name(f"{out.stem}_{k:03d}.png")) for k in range(2)])
    moved, still = outs
    assert np.array_equal(moved[0], still[0]) and not np.array_equal(moved[1], still[1])
