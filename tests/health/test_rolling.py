"""The rolling self-check (issue 43, item 2): a few tiles per frame within a share of the sensor's time, one
line when the verdict crosses the tolerance; in ``psvs live``, its log columns (csv) and MCAP records (the
``mcap`` reader)."""
import csv
import json
import math

import numpy as np
import pytest

from psvs.cli.main import main
from psvs.health.rolling import SHARE, TILES_PER_STEP, RollingCheck
from psvs.health.rows import frame_tiles
from psvs.io.params import load_rig
from psvs.simulate.builtin import textured, wall
from psvs.simulate.render import render
from tests.support.mcap import read_mcap


@pytest.fixture(scope="module")
def frames():
    """Frames of a wall and the textured scene through the misaligned build and through it knocked."""
    out = {}
    for name in ("misaligned", "misaligned_knocked"):
        rig = load_rig(name)
        out[name] = [render(wall(650.0, 1), rig, seed=1, supersample=1).image,
                     render(textured(800.0), rig, seed=2, supersample=1).image,
                     render(wall(950.0, 3), rig, seed=3, supersample=1).image]
    return out


def run_check(images, n=400, sensor_s=0.05, rig="misaligned"):
    check = RollingCheck(load_rig(rig))
    events = [e for k in range(n) if (e := check.step(images[k % len(images)], k, sensor_s)) is not None]
    return check, events


def test_a_knock_is_said_once_and_the_figure_is_the_checks(frames):
    """Knocked frames read through the old calibration: one event, drifted, with the field near the 2.46 px
    psvs check measures on whole frames; the check took at most its share of the sensor's time (one step's
    overshoot allowed: a step starts while credit is left and costs what it costs. On a loaded machine a step
    can take many times the mean: a fresh clone's run overshot a bound of two mean steps by 0.54 s, its last
    step having waited for the other test worker. The bound is the accounting's own: credit in, the share of
    the sensor's time; out, each step's time; a step only on credit, so at most the last step's time is
    owed)."""
    check, events = run_check(frames["misaligned_knocked"])
    assert [e.check.verdict for e in events] == ["drifted"]
    assert "the calibration has drifted" in events[0].line and events[0].frame < 200
    assert check.latest.verdict == "drifted" and abs(check.latest.row_offset_rms_px - 2.46) <= 0.4
    assert 0 < check.last_step_s and check.spent_s <= SHARE * check.sensor_s + check.last_step_s + 1e-9
    assert check.steps >= 10


def test_an_undrifted_build_raises_no_alarm(frames):
    check, events = run_check(frames["misaligned"])
    assert events == [] and check.latest.verdict == "healthy", check.latest.reason


def test_idle_steps_run_when_told_and_the_sensor_does_not_pay_for_them(frames):
    """Steps on time the sensor does not need (a tracking run's run-in, psvs.robot.drift) run whether or not
    the sensor's share has bought one, and are counted apart: neither taken off the credit nor in the check's
    share of the sensor's time. A sweep is done once every place of the field has been read."""
    check = RollingCheck(load_rig("misaligned"))
    places = len(frame_tiles(frames["misaligned"][0], check.rig).places_px)
    k = 0
    while not check.swept:
        assert not check.due(0.005)                                         # 8 % of 5 ms: 0.4 ms, not a step
        check.take(frames["misaligned"][k % 3], k, idle=True)
        k += 1
    assert check.idle_steps == check.steps == k == math.ceil(places / TILES_PER_STEP) and check.cost_share == 0.0
    assert check.idle_spent_s == check.spent_s > 0
    n = 1              # the sweep owes nothing: the share buys its next step as if the sweep had not run (a
    while not check.due(0.05):          # step's cost, some frames of 4 ms), not after paying the sweep's time
        n += 1
    assert n * SHARE * 0.05 < check.idle_spent_s / 2, (n, check.idle_spent_s)
    check.take(frames["misaligned"][0], k)                                 # one on the sensor's share
    assert check.cost_share == pytest.approx((check.spent_s - check.idle_spent_s) / check.sensor_s)
    assert 0 < check.cost_share and check.idle_spent_s < check.spent_s
    assert check.summary()["idle_steps"] == k and check.summary()["steps"] == k + 1


def test_no_step_without_time(frames):
    """A sensor that spends no time on a frame gives the check none: it never runs."""
    check, events = run_check(frames["misaligned"], n=20, sensor_s=0.0)
    assert check.steps == 0 and check.latest is None and events == []
    with pytest.raises(ValueError, match="share"):
        RollingCheck(load_rig("misaligned"), share=0.0)


def test_live_logs_the_check_and_says_the_drift(tmp_path, capsys, frames):
    """psvs live on a knocked build's video: one line saying the drift, the log's health columns (read with
    csv), the /psvs/health records of the recording (read with the mcap reader) agreeing with the log; with
    --no-check neither."""
    from psvs.io.video import write_video
    video = tmp_path / "knocked.avi"
    write_video(video, [frames["misaligned_knocked"][k % 3] for k in range(24)], 30.0)
    log, rec = tmp_path / "live.csv", tmp_path / "live.mcap"
    # 30 % of the sensor's time (not the default 8 %): the steps that 24 frames pay for then cover enough of
    # the field however busy the machine (at 8 % a loaded machine's run judged one step: cannot judge)
    # the dense maps through the old calibration have no echo to stand on (the twins 2.5 px off their rows): no
    # depth, exit 1 -- and the check says why
    assert main(["live", "--video", str(video), "--rig", "misaligned", "--dense", "--fast", "--quiet", "-o", str(log),
                 "--mcap", str(rec), "--check-share", "30"]) == 1
    out, err = capsys.readouterr()
    assert "no frame's echo stands above chance" in err
    assert out.count("the calibration has drifted") == 1 and "self-check: drifted" in out
    with log.open() as f:
        rows = list(csv.DictReader(f))
    judged = [r for r in rows if r["health"]]
    assert judged and judged[-1]["health"] == "drifted" and abs(float(judged[-1]["row_offset_rms_px"]) - 2.46) < 0.5
    _, _, msgs = read_mcap(rec)
    records = [json.loads(m.data) for _, c, m in msgs if c.topic == "/psvs/health"]
    assert records and records[-1]["verdict"] == "drifted"
    last = rows[records[-1]["frame"]]
    assert float(last["row_offset_rms_px"]) == pytest.approx(records[-1]["row_offset_rms_px"], abs=1e-4)
    assert int(last["health_tiles"]) == records[-1]["tiles"] and 0 < records[-1]["cost_share"] < 0.5
    assert main(["live", "--video", str(video), "--rig", "misaligned", "--dense", "--fast", "--quiet", "-o", str(log),
                 "--no-check", "--max-frames", "3"]) == 1
    assert "self-check" not in capsys.readouterr().out
    with log.open() as f:
        assert "health" not in f.readline()
    assert not any(np.isfinite(float(r["dense_median_z_mm"] or "nan")) for r in rows)      # no depth from no echo


@pytest.mark.parametrize("rig_name, start", [("misaligned_knocked", 0), ("misaligned_knocked", 37), ("default", 5)])
def test_a_steps_tiles_read_on_bands_are_the_whole_grids(frames, rig_name, start):
    """A step's tiles, made from only the grid rows they and their chance bands read, are the tiles of the
    whole frame's grids (the same values to float rounding), on a build and on the paper's geometry."""
    from psvs.health.rows import frame_tiles
    rig = load_rig(rig_name)
    image = frames["misaligned_knocked"][1] if rig_name != "default" else \
        render(textured(800.0), rig, seed=4, supersample=1).image
    whole = frame_tiles(image, rig)
    part = frame_tiles(image, rig, subset=(start, 12))
    k = [(start + i) % whole.of_tiles for i in range(12)]
    assert part.of_tiles == whole.of_tiles and len(part.offset_px) == 12
    np.testing.assert_allclose(part.centre_px, whole.centre_px[k])
    for name in ("offset_px", "disparity_px", "score", "chance"):
        np.testing.assert_allclose(getattr(part, name), getattr(whole, name)[k], atol=1e-4, equal_nan=True)
    assert (part.accepted == whole.accepted[k]).all() and part.accepted.sum() >= 6
