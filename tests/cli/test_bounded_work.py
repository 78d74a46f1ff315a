"""No command starts work it cannot finish: counts and sizes are checked against the time and memory they
imply before any work (psvs._budget, psvs._budget), and a rig outside the physical bounds is refused when it
is loaded. Each refusal: exit status 2, one line on stderr naming the option (or the rig's key) with the
estimate and the limit, within seconds, and an earlier output file left as it was. psvs design answers in
seconds on the most extreme rigs the bounds allow."""
import math
import re
from pathlib import Path

import numpy as np
import pytest

from psvs import _budget, default_rig
from psvs.io.params import save_rig
from psvs.optics.rig import MirrorError
from tests.support.cli import run, user_cpu_s

ROOT = Path(__file__).resolve().parents[2]
#: A hang detector, not a benchmark: every refusal comes before any work. User-mode CPU time of this process
#: (every thread: tests.support.cli.user_cpu_s).
QUICK_S = 10.0


def refused(capsys, argv, expected: str, keep=()):
    """Run ``psvs ARGV`` in-process: exit status 2, one line on stderr holding ``expected``, within
    :data:`QUICK_S`, and the files ``keep`` unchanged."""
    before = {p: p.read_bytes() for p in keep}
    t0 = user_cpu_s()
    code, _, err = run(capsys, *[str(a) for a in argv])
    took = user_cpu_s() - t0
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert expected in err, err
    assert took < QUICK_S, f"{took:.1f} s: {err}"
    for p, b in before.items():
        assert p.read_bytes() == b, p
    return err


def earlier(path, text="earlier\n"):
    """An output file from an earlier run."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def rig_file(tmp_path, name="rig.toml", **changes):
    path = tmp_path / name
    save_rig(default_rig().replace(**changes), path)
    return path


@pytest.fixture
def plenty_of_memory(monkeypatch):
    """1 TiB available: the time limit is what refuses (the memory check is tested on its own)."""
    monkeypatch.setattr(_budget, "available_bytes", lambda: 1 << 40)


# ---- card-views --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("args, expected", [
    (["--rows", "1000", "--cols", "1000"],
     "card (--rows 1000 --cols 1000 --spacing-mm 14 --diameter-mm 7): the grid of discs is 13993 x 13993 mm "
     "(1000 x 1000 discs 14 mm apart, 7 mm across); this rig's views hold at most 95 x 230 mm of it at 450-484 mm, "
     "the nearest of the 16 poses (both copies of the grid side by side, apart)"),        # (no --interleave fits it)
    # trial 52: a card wider than its disparity, refused with its copy apart (it fits interleaved): the
    # message names --interleave
    (["--rows", "4", "--cols", "8"], "the grid of discs is 105 x 49 mm (8 x 4 discs 14 mm apart, 7 mm across); "
                                     "this rig's views hold at most 95 x 230 mm of it at 450-484 mm, "
                                     "the nearest of the 16 poses (both copies of the grid side by side, apart: a "
                                     "card wider than its disparity interleaves with its copy, as a hand-held one "
                                     "does: psvs card-views --interleave)"),
    (["--rows", "100", "--cols", "100", "--spacing-mm", "0.9", "--diameter-mm", "0.5"],
     "the discs (0.5 mm) are 0.56 px across at 966-1000 mm, the farthest poses, through this rig; the detector "
     "finds discs 3.9-40 px across: none of the 10000 would be found"),
    (["--rows", "2", "--cols", "2", "--spacing-mm", "21", "--diameter-mm", "20"],
     "the discs (20 mm) are 42.3 px across at 450-484 mm, the nearest poses"),
])
def test_card_views_refuses_a_card_the_views_cannot_hold(capsys, tmp_path, args, expected):
    """--rows 1000 --cols 1000 ran past 150 s without a word (2000 pose tries a view, each projecting a
    million discs); now the card's size is checked against the rig's views before any pose is tried."""
    target = earlier(tmp_path / "cards" / "target.toml")
    refused(capsys, ["card-views", tmp_path / "cards", "--rig", "default", *args], expected, [target])


#: A 30-Mpx camera (the paper's lens and pixels on a 64 x 48 mm sensor)
BIG = dict(image_size_px=(6400, 4800), principal_point_px=(3199.5, 2399.5))


def test_card_views_refuses_renders_beyond_the_time_limit(capsys, tmp_path, plenty_of_memory):
    rig = rig_file(tmp_path, **BIG)
    target = earlier(tmp_path / "cards" / "target.toml")
    refused(capsys, ["card-views", tmp_path / "cards", "--rig", rig, "--views", "60"],
            "--views 60 (60 render(s) of 6400x4800 px x 4 sample(s) per pixel: 7.37e+09 samples at 1 us each) "
            "takes about 2.05 h, more than the 1 h limit; fewer --views", [target])


def test_card_views_refuses_a_render_beyond_the_memory(capsys, tmp_path, monkeypatch):
    monkeypatch.setattr(_budget, "available_bytes", lambda: 4 << 30)
    rig = rig_file(tmp_path, **BIG)
    refused(capsys, ["card-views", tmp_path / "cards", "--rig", rig],
            "--views 16: one render of 6400x4800 px x 4 sample(s) per pixel needs about 34.3 GiB of memory, "
            "more than the 3.2 GiB available")


def test_the_memory_a_user_states_is_the_memory_the_guard_sees(capsys, tmp_path, monkeypatch):
    """$PSVS_MEMORY_AVAILABLE_MIB (a shared machine; the tests pin it) replaces the system's figure, in MiB;
    a value that is not a positive number is refused in one line naming the variable."""
    monkeypatch.setenv(_budget.AVAILABLE_ENV, "4096")
    assert _budget.available_bytes() == 4 << 30
    rig = rig_file(tmp_path, **BIG)
    refused(capsys, ["card-views", tmp_path / "cards", "--rig", rig],
            "needs about 34.3 GiB of memory, more than the 3.2 GiB available")
    for bad in ("", "lots", "0", "-5", "nan", "inf"):
        monkeypatch.setenv(_budget.AVAILABLE_ENV, bad)
        refused(capsys, ["card-views", tmp_path / "cards", "--rig", rig],
                f"PSVS_MEMORY_AVAILABLE_MIB must be a positive number of MiB, got {bad!r}")


# ---- sweep-views -------------------------------------------------------------------------------------------

@pytest.mark.parametrize("args, expected", [
    (["--step-mm", "1e-9"], "the sweep has 750000000001 positions; give 3-60 (--from-mm, --to-mm, --step-mm)"),
    (["--from-mm", "1", "--to-mm", "1e300", "--step-mm", "1e299"], "the sweep's depths 1-9e+299 mm lie outside"),
    (["--from-mm", "1", "--to-mm", "1e9", "--step-mm", "1e8"],
     "--from-mm/--to-mm: the sweep's depths 1-9e+08 mm lie outside 299-2841 mm, where this rig shows the Fig. 9 "
     "pattern so that it is found (both copies of its row of circles in the image, each circle at least 3.9 px "
     "across)"),
    (["--from-mm", "100", "--to-mm", "300", "--step-mm", "100"], "the sweep's depths 100-300 mm lie outside"),
])
def test_sweep_views_refuses_a_step_or_range_it_cannot_use(capsys, tmp_path, args, expected):
    """np.arange(425, 1175, 1e-9) was allocated before the count was checked; now the count comes first,
    and the depths must be where the pattern can be found through the rig."""
    csv = earlier(tmp_path / "sw" / "sweep.csv")
    refused(capsys, ["sweep-views", tmp_path / "sw", "--rig", "default", *args], expected, [csv])


def test_sweep_views_refuses_renders_beyond_the_time_limit(capsys, tmp_path, plenty_of_memory):
    """A 10-times finer camera sees the pattern at 2.8-29 m only (its circles must stay under 40 px)."""
    rig = rig_file(tmp_path, image_size_px=(6400, 4800), pixel_pitch_mm=(0.001, 0.001),
                   principal_point_px=(3199.5, 2399.5))
    refused(capsys, ["sweep-views", tmp_path / "sw", "--rig", rig, "--from-mm", "3000", "--to-mm", "8900",
                     "--step-mm", "100"],
            "the sweep's 60 positions (60 render(s) of 6400x4800 px x 4 sample(s) per pixel", [])


# ---- simulate ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("args, expected", [
    (["--frames", "100000"], "--frames 100000 x --supersample 2 (100000 render(s) of 640x480 px x 4 sample(s) per "
                             "pixel: 1.23e+11 samples at 1 us each) takes about 1.42 days, more than the 1 h limit; "
                             "fewer --frames or a smaller --supersample"),
    (["--frames", "5000", "--truth", "{tmp}/t.npz"], "with ground truth: 9.22e+09 samples at 1 us each) takes about "
                                                     "2.56 h"),
    (["--frames", "1000000000000"], "--frames 1000000000000 x --supersample 2"),
    (["--blur-px", "1e6"], "--blur-px must be at most 100 px (a lens's blur), got 1000000.0"),
])
def test_simulate_refuses_work_beyond_the_limits(capsys, tmp_path, args, expected):
    """frames x supersample x image size: rendering time, before the scene is built or a frame rendered."""
    out = earlier(tmp_path / "s.png", "an earlier image")
    refused(capsys, ["simulate", "fig5b", "-o", out, *[a.format(tmp=tmp_path) for a in args]], expected, [out])


def test_simulate_refuses_a_seam_no_cell_holds(capsys, tmp_path):
    out = earlier(tmp_path / "s.png", "an earlier image")
    refused(capsys, ["simulate", "weld_seam:length_mm=1e7,radius_mm=1e7", "-o", out],
            "weld_seam: length_mm must be at most 2000 mm", [out])


# ---- table1 ------------------------------------------------------------------------------------------------

def test_table1_refuses_renders_beyond_the_time_limit(capsys, tmp_path, plenty_of_memory):
    rig = rig_file(tmp_path, image_size_px=(8000, 6000), pixel_pitch_mm=(0.0008, 0.0008),
                   principal_point_px=(3999.5, 2999.5))
    table = earlier(tmp_path / "t1" / "table1.csv")
    refused(capsys, ["table1", "--rig", rig, "-o", tmp_path / "t1"],
            "Table I's 31 renders (31 render(s) of 8000x6000 px x 4 sample(s) per pixel: 5.95e+09 samples at 1 us "
            "each) takes about 1.65 h, more than the 1 h limit; a rig with a smaller camera", [table])


def test_table1_refuses_a_rig_that_cannot_see_the_pattern(capsys, tmp_path):
    """1 um pixels: the Fig. 9 pattern's discs (230 px at 440 mm) are found at the sizes the rig gives them
    (psvs.targets.pattern.disc_size_range_px), but the hand-held card's (found at 3.9-40 px) are not."""
    rig = rig_file(tmp_path, image_size_px=(6400, 4800), pixel_pitch_mm=(0.001, 0.001),
                   principal_point_px=(3199.5, 2399.5))
    table = earlier(tmp_path / "t1" / "table1.csv")
    refused(capsys, ["table1", "--rig", rig, "-o", tmp_path / "t1", "--card"],
            "the discs (7 mm) are 149 px across at 450-481 mm, the nearest poses, through this rig; the detector "
            "finds discs 3.9-40 px across", [table])


def test_table1_refuses_a_narrow_rig(capsys, tmp_path):
    """A 60 mm baseline, its mirrors where `psvs design` puts them for it (a clear layout)."""
    rig = rig_file(tmp_path, baseline_mm=60.0, m1_axis_distance_mm=12.5, m2_axis_distance_mm=26.640625)
    refused(capsys, ["table1", "--rig", rig, "-o", tmp_path / "t1"],
            "the Fig. 9 pattern (90 mm wide) is wider than this rig's baseline (60 mm): its two copies overlap at "
            "every depth")


def test_table1_refuses_a_start_of_another_camera_before_rendering(capsys, tmp_path):
    """Issue 41: `table1 --rig mv1440 --start default` rendered before noticing the start is a 640x480
    camera: refused first, one line, the table kept."""
    table = earlier(tmp_path / "t1" / "table1.csv")
    refused(capsys, ["table1", "--rig", "mv1440", "--start", "default", "-o", tmp_path / "t1"],
            "the start rig is another camera: 640x480 px of 10 um, the build's 1440x1080 px of 3.45 um: start "
            "from the build's own design", [table])


def test_table1_refusal_at_a_test_distance_ends_the_bar_and_names_the_distance(capsys, tmp_path):
    """Trial 31: on a build whose sweep calibration cannot measure a test pattern, the refusal was written onto
    the progress bar's line and advised --near-mm/--far-mm, which table1 does not have (its patterns stand at
    known distances). Now the bar's line is ended first, the refusal names the test distance and the
    calibration, and no option table1 lacks."""
    code, _, err = run(capsys, "table1", "--rig", "misaligned_knocked", "-o", str(tmp_path / "t1"))
    last = err.replace("\r", "\n").rstrip("\n").split("\n")[-1]
    assert code == 1 and err.endswith("\n") and "near-mm" not in err, err
    assert re.match(r"psvs table1: cannot measure: the test pattern at \d+ mm does not measure through the rig "
                    r"calibrated from the robot sweep \(RMS \d\.\d{3} px\): ", last), last
    assert err.count("psvs table1:") == 1 and not (tmp_path / "t1").exists()


# ---- handeye, track, live ----------------------------------------------------------------------------------

@pytest.mark.parametrize("count, expected", [
    ("100000", "--views-count 100000 (100000 render(s) of 640x480 px x 1 sample(s) per pixel: 3.07e+10 samples at "
               "1 us each) takes about 8.53 h, more than the 1 h limit; fewer --views-count"),
    ("2", "--views-count must be at least 3"),
])
def test_handeye_refuses_a_session_beyond_the_limits(capsys, tmp_path, count, expected):
    out = earlier(tmp_path / "he.toml")
    refused(capsys, ["handeye", "--rig", "default", "--views-count", count, "-o", out], expected, [out])


def _seam_after_arc_mm() -> float:
    from scipy.integrate import quad
    r, length, rise = 150.0, 240.0, 20.0
    speed = lambda x: math.sqrt(1 + (x / math.sqrt(r * r - x * x)) ** 2  # noqa: E731
                                + (rise * math.pi / length * math.cos(math.pi * x / length)) ** 2)
    return round(quad(speed, -length / 2, length / 2)[0] - 50.0, 3)


SEAM_AFTER_ARC_MM = _seam_after_arc_mm()


@pytest.mark.parametrize("args, expected, limit_s", [
    (["--speed", "0.001", "--no-check"], "--length/--speed/--rate: 8500000 control cycles (240 mm of seam and 100 "
                                         "mm to start and stop at 0.001 mm/s, 25 Hz), each a 640x32 px window x 4 "
                                         "samples and 10 ms of sensing, takes about 9.04 days, more than the 1 h "
                                         "limit; a higher --speed, a lower --rate or a shorter --length", 3600.0),
    # the self-check's whole frames: 8 % of 10 ms of sensing a cycle buys a 30 ms step every 37.5 cycles, each
    # frame 640 x 480 x 4 samples at 1 us: 226667 x 1.23 s = 3.22 days more
    (["--speed", "0.001"], "of sensing and 226667 whole frames for the self-check (--no-check leaves them out), "
                           "takes about 12.3 days", 3600.0),
    (["--speed", "0.1", "--rate", "250"], "850000 control cycles (240 mm of seam", 3600.0),
    # a length beyond the seam (its curve: 232.07 mm past the arc's start at 50 mm, an arc of radius 150 mm over
    # 240 mm with a 20 mm rise, integrated here independently) or not a number (report.json held Infinity)
    (["--length", "1e9"], f"--length 1e+09 mm is longer than the seam's {SEAM_AFTER_ARC_MM:g} mm from where the "
                          "arc is struck (50 mm in) to its end", 3600.0),
    (["--length", "inf"], "weld_length_mm must be a number > 0, got inf", 3600.0),
    # 5000 cycles at 0.092 s: 7.7 min, within the hour; refused by a one-minute limit
    (["--speed", "1", "--length", "100"], "5000 control cycles (100 mm of seam", 60.0),
    (["--roi-rows", "100000"], "--roi-rows must be at most the camera's 480 rows, got 100000", 3600.0),
])
def test_track_refuses_a_run_beyond_the_limits(capsys, tmp_path, args, expected, limit_s, monkeypatch):
    """Checked before the hand-eye session (12 s) and the first cycle."""
    monkeypatch.setattr(_budget, "WORK_LIMIT_S", limit_s)
    report = earlier(tmp_path / "run" / "report.json")
    refused(capsys, ["track", "weld_seam", "--rig", "default", "-o", tmp_path / "run", "--no-bag", *args],
            expected, [report])


def test_track_estimates_the_default_run_within_the_limit():
    """The default job (240 mm at 10 mm/s, 25 Hz, 640x32 window): 850 cycles, about 78 s (it takes ~60 s)."""
    from psvs.robot.controller import TrackConfig
    from psvs.robot.loop import cycle_seconds, track_cycles
    cfg = TrackConfig()
    assert track_cycles(240.0, cfg) == 850
    assert 0.05 < cycle_seconds(default_rig(), cfg) < 0.2


def test_live_refuses_frames_beyond_the_memory(capsys, tmp_path, monkeypatch):
    """What a run keeps of every frame for its log (32 KiB) times --max-frames, or the video's own count
    when smaller: a 64 x 48 px camera (192 KiB a frame to load its rig) and room for 7 frames' records."""
    from psvs.cli.live_cmd import KEPT_BYTES_PER_FRAME
    from psvs.io.video import write_video
    video = tmp_path / "v.avi"
    write_video(video, [np.full((48, 64), 100 + k, np.uint8) for k in range(10)], fps=25)
    rig = rig_file(tmp_path, image_size_px=(64, 48), pixel_pitch_mm=(0.1, 0.1), principal_point_px=(31.5, 23.5))
    log = earlier(tmp_path / "log.csv")
    monkeypatch.setattr(_budget, "available_bytes", lambda: int(7 * KEPT_BYTES_PER_FRAME / 0.8))
    live = ["live", "--video", video, "--rig", rig, "--seed", "1,2", "-o", log]
    refused(capsys, [*live, "--max-frames", "8"], "--max-frames 8 (32 KiB kept a frame for the log) needs about "
                                                  "256.0 KiB of memory, more than the 224.0 KiB available; fewer "
                                                  "--max-frames", [log])
    refused(capsys, live, f"{video}'s 10 frames (32 KiB kept a frame for the log) needs about 320.0 KiB", [log])
    code, _, err = run(capsys, *[str(a) for a in live[:-2]], "--max-frames", "6", "--quiet")
    assert code in (0, 1) and "memory" not in err, err     # it runs (a blank video: no edge to track)


def test_live_dense_keeps_no_maps():
    from psvs.live.dense import DenseFrame
    d = DenseFrame(0, np.zeros((240, 320), np.float32), (1.0, 60.0), np.zeros((100, 3)), np.zeros((100, 2)),
                   np.zeros((60, 80)), 700.0, 80.0, 0.01)
    b = d.brief()
    assert b.disparity_px.size == 0 and b.points_mm.shape == (0, 3) and b.depth_mm.size == 0
    assert (b.frame, b.median_z_mm, b.answered_pct, b.elapsed_s) == (0, 700.0, 80.0, 0.01)


# ---- a rig outside the bounds, through the commands ---------------------------------------------------------

@pytest.mark.parametrize("argv, keep", [
    (["design", "--rig", "{rig}", "-o", "{tmp}/out.json"], "out.json"),
    (["triangulate", "--rig", "{rig}", "{tmp}/m.csv", "-o", "{tmp}/out.csv"], "out.csv"),
    (["simulate", "fig5b", "--rig", "{rig}", "-o", "{tmp}/out.png"], "out.png"),
    (["card-views", "{tmp}/cards", "--rig", "{rig}"], "cards/target.toml"),
    (["track", "weld_seam", "--rig", "default", "--true-rig", "{rig}", "-o", "{tmp}/run"], "run/report.json"),
])
def test_an_implausible_rig_is_refused_when_loaded(capsys, tmp_path, argv, keep):
    rig = tmp_path / "tilted.toml"
    rig.write_text((ROOT / "examples" / "rigs" / "misaligned.toml").read_text()
                   .replace("tilt_deg = [-0.22, -0.14]", "tilt_deg = [89.0, -0.14]"))
    (tmp_path / "m.csv").write_text("u_l,v_l,u_r,v_r\n400,240,200,240\n")
    out = earlier(tmp_path / keep)
    refused(capsys, [a.format(rig=rig, tmp=tmp_path) for a in argv],
            f"{rig}: mirrors.m2.tilt_deg[0] = 89 deg is outside a build's errors (-6..6 deg)", [out])


# ---- design on the most extreme rigs the bounds allow ------------------------------------------------------

T6 = math.radians(6.0)
EXTREMES = {
    "every error at its bound": dict(box_rotation_rad=(T6, T6, -T6)),
    "widest, farthest mirrors": dict(baseline_mm=1000.0, m1_axis_distance_mm=999.0, m2_axis_distance_mm=1000.0),
    "thickest, densest plate far out": dict(plate_thickness_mm=30.0, refractive_index=2.5, m1_axis_distance_mm=900.0,
                                            m2_axis_distance_mm=1000.0),
    "strongest lens": dict(distortion=(-3.0, -3.0, -0.3, -0.3, -3.0), baseline_mm=1000.0, m1_axis_distance_mm=999.0,
                           m2_axis_distance_mm=1000.0),
    "widest field": dict(focal_length_mm=0.5, pixel_pitch_mm=(0.0005, 0.0005), angle_rad=math.radians(70.0),
                         baseline_mm=1000.0, m1_axis_distance_mm=999.0, m2_axis_distance_mm=1000.0),
    "longest lens, flattest mirrors": dict(focal_length_mm=2000.0, angle_rad=math.radians(20.0), baseline_mm=1000.0,
                                           m1_axis_distance_mm=999.0, m2_axis_distance_mm=1000.0),
}


@pytest.mark.parametrize("name", EXTREMES)
def test_design_answers_in_seconds_on_the_extreme_rigs(capsys, tmp_path, name):
    """A blocked layout's search for a clear one ran past a minute on tilted rigs; it now traces at most 1000
    layouts (a few seconds) and says when it stopped there."""
    rig = default_rig().replace(**EXTREMES[name])
    if name == "every error at its bound":
        rig = rig.with_errors({n: MirrorError((T6, -T6), 25.0 if n in ("m1", "m3") else -25.0)
                               for n in ("m1", "m2", "m3", "m4")})
    path = tmp_path / "extreme.toml"
    save_rig(rig, path)
    t0 = user_cpu_s()
    code, out, err = run(capsys, "design", "--rig", str(path), "-o", str(tmp_path / "t.json"))
    took = user_cpu_s() - t0
    assert took < QUICK_S, f"{took:.1f} s"
    assert code in (0, 1, 2), err
    if code == 2:     # the field reaches no mirror: refused in one line
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    else:
        assert "Layout:" in out


def test_design_does_not_write_a_rig_outside_the_bounds(capsys, tmp_path):
    """The strongest lens's field needs mirrors 126 m long: --rig-out refuses before either file is written."""
    rig = rig_file(tmp_path, distortion=(-3.0, -3.0, -0.3, -0.3, -3.0), baseline_mm=1000.0, m1_axis_distance_mm=999.0,
                   m2_axis_distance_mm=1000.0)
    table, designed = earlier(tmp_path / "t.json"), earlier(tmp_path / "designed.toml")
    refused(capsys, ["design", "--rig", rig, "--no-search", "--near-mm", "1500", "--far-mm", "3000", "-o", table,
                     "--rig-out", designed],
            "is outside a mirror rig's size (-10000..10000 mm)", [table, designed])


@pytest.mark.parametrize("argv", [["triangulate", "{rig}", "MATCHES", "-o", "{out}/p.csv"],
                                  ["export-calibration", "{rig_path}", "-o", "{out}/ros"],
                                  ["fit-refraction", "{rig}", "KNOWN", "-o", "{out}/f.toml"]])
def test_a_blocked_rig_is_refused_before_any_answer(capsys, tmp_path, argv):
    """Issue 41: a rig `psvs design` calls BLOCKED (5 mm baseline behind a 30 mm plate) gave points marked
    valid and a ROS calibration: now exit 2, one line, nothing written."""
    from tests.support.geometry import EXAMPLES
    rig = rig_file(tmp_path, baseline_mm=5.0, plate_thickness_mm=30.0)
    out = tmp_path / "out"
    out.mkdir()
    words = []
    for a in argv:
        if a == "{rig}":
            words += ["--rig", rig]
        else:
            words.append(a.format(rig_path=rig, out=out).replace("MATCHES", str(EXAMPLES / "matches.csv"))
                         .replace("KNOWN", str(EXAMPLES / "known_points.csv")))
    refused(capsys, words, "is no layout a build can have: ")
    assert list(out.iterdir()) == []
