"""psvs montecarlo on a real 2-worker LocalCluster: each sample of a study is exactly what that build gives
calibrated alone; a worker killed mid-study loses no finished sample and the study completes; a second run
over a finished folder computes nothing (a larger -n only the new samples); an unreachable scheduler is one
line, exit 2, nothing written."""
from __future__ import annotations

import math
import os
import signal
import threading
import time

import pyarrow.parquet as pq
import pytest

from psvs.cluster import RunOptions, connect, read_results
from psvs.io.params import load_rig
from psvs.study.montecarlo import prepare_study, run_study
from psvs.study.sample import STUDY_TMP_ENV, TIMING, run_sample
from psvs.study.tolerances import tolerances_from_dict
from tests.support.cli import run

#: A cheap study: the default rig's shipped tolerances, 4 card views at 1x1, a small test set.
SMALL = {"tolerances": {"mirror_tilt_deg": {"uniform": 0.2}, "mirror_shift_mm": {"uniform": 0.5},
                        "focal_length_mm": {"normal": 0.1}},
         "calibration": {"views": 4, "supersample": 1}, "test": {"depths": 3, "grid": 5},
         "targets": {"rms_3d_mm": 5.0}}
QUIET = RunOptions(progress=False, label="montecarlo")
SEED = 11


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    """A 2-worker LocalCluster whose samples render under a pytest folder (as ``psvs montecarlo`` gives its
    workers one): the worker the test kills leaves its half-rendered card views there, not in TMPDIR."""
    renders = tmp_path_factory.mktemp("renders")
    before = os.environ.get(STUDY_TMP_ENV)
    os.environ[STUDY_TMP_ENV] = str(renders)            # inherited by the workers as they start
    try:
        with connect(workers=2) as c:
            yield c
    finally:
        if before is None:
            os.environ.pop(STUDY_TMP_ENV, None)
        else:
            os.environ[STUDY_TMP_ENV] = before


@pytest.fixture(scope="module")
def study():
    nominal, tol = load_rig("default"), tolerances_from_dict(SMALL)
    return nominal, tol


def _parts(out) -> list:
    """The part files a running study has written so far."""
    return sorted((out / "parts").glob("part-*.parquet")) if (out / "parts").is_dir() else []


def _same(a: dict, b: dict, skip=TIMING) -> bool:
    """Equal rows (NaN equal to NaN), the columns ``skip`` aside."""
    keys = set(a) - set(skip)
    return keys == set(b) - set(skip) and all(
        a[k] == b[k] or (isinstance(a[k], float) and math.isnan(a[k]) and math.isnan(b[k])) for k in keys)


@pytest.mark.slow
def test_each_sample_is_what_its_build_gives_alone_and_a_rerun_computes_nothing(client, study, tmp_path):
    nominal, tol = study
    out = tmp_path / "study"
    params, _ = prepare_study(nominal, tol, SMALL, 4, SEED, out)
    res = run_study(client, nominal, tol, 4, out, params, QUIET)
    assert res.summary.computed == 4 and res.summary.failed == {}
    assert [r["index"] for r in res.rows] == list(range(4))
    for r in (res.rows[0], res.rows[-1]):         # the first and last sample, each as its build gives alone
        assert _same(r, run_sample(nominal, tol, SEED, r["index"])), r["index"]
    assert len({r["dev_m1_tilt_b_deg"] for r in res.rows}) == 4         # four different builds
    again = run_study(client, nominal, tol, 4, out, prepare_study(nominal, tol, SMALL, 4, SEED, out)[0], QUIET)
    assert again.summary.computed == 0 and again.summary.skipped == 4
    assert all(_same(a, b) for a, b in zip(again.rows, res.rows, strict=True))
    more = run_study(client, nominal, tol, 5, out, params, QUIET)
    assert more.summary.computed == 1 and len(more.rows) == 5
    assert _same(more.rows[4], run_sample(nominal, tol, SEED, 4))
    import json
    scores = json.loads((out / "scores.json").read_text())
    assert scores["samples"] == 5 and scores["ok"] == sum(r["ok"] for r in more.rows)


@pytest.mark.slow
def test_a_killed_worker_loses_no_finished_sample(client, study, tmp_path):
    nominal, tol = study
    out = tmp_path / "study"
    params, _ = prepare_study(nominal, tol, SMALL, 4, SEED + 1, out)
    result = {}
    runner = threading.Thread(target=lambda: result.update(r=run_study(client, nominal, tol, 4, out, params, QUIET)))
    runner.start()
    t0 = time.monotonic()
    while not _parts(out):
        assert time.monotonic() - t0 < 300, "no sample finished within 300 s"
        time.sleep(0.1)
    finished = {r["key"]: r for f in _parts(out) for r in pq.read_table(f).to_pylist()}
    pids = client.run(os.getpid)
    os.kill(next(iter(pids.values())), signal.SIGKILL)
    runner.join(timeout=600)
    assert not runner.is_alive()
    res = result["r"]
    assert res.summary.complete and res.summary.failed == {} and len(res.rows) == 4
    table = {r["key"]: r for r in read_results(out).to_pylist()}
    assert all(_same(table[k], r, ()) for k, r in finished.items())   # what was written before the kill, as it was
    # one sample finished before the kill and one after, each as its build gives alone
    after = min(set(range(4)) - set(finished), default=3)
    for k in (min(finished), after):
        assert _same({c: v for c, v in table[k].items() if c != "key"}, run_sample(nominal, tol, SEED + 1, k))
    client.wait_for_workers(2, timeout=60)


def test_an_unreachable_scheduler_is_one_line_and_writes_nothing(capsys, tmp_path):
    out = tmp_path / "study"
    code, text, err = run(capsys, "montecarlo", "--rig", "default", "--tolerances", "default", "-n", "4", "-o",
                          str(out), "--scheduler", "tcp://127.0.0.1:9")
    assert code == 2 and len(err.strip().splitlines()) == 1 and "cannot reach the Dask scheduler" in err, err
    assert not out.exists()


def test_a_folder_of_another_study_is_refused_before_any_work(study, tmp_path):
    nominal, tol = study
    out = tmp_path / "study"
    out.mkdir()
    (out / "study.json").write_text('{"study": "psvs montecarlo", "seed": 1}')
    with pytest.raises(ValueError, match="other parameters"):
        prepare_study(nominal, tol, SMALL, 6, SEED, out)
    with pytest.raises(ValueError, match="-n must be"):
        prepare_study(nominal, tol, SMALL, 0, SEED, tmp_path / "other")


@pytest.mark.parametrize("table, front", [("test", 30.0), ("calibration", 40.0)])
def test_a_range_inside_the_mirror_box_is_refused_before_any_work(capsys, tmp_path, table, front):
    """Trial 46: a tolerances file whose test set (or simulated calibration) starts at 30 mm, inside the mirror
    box, was scored (exit 0), where every command's working range is refused there. Exit 2, one line naming
    the key and where the mirrors reach, no folder."""
    tol = tmp_path / "t.toml"
    tol.write_text(f"[tolerances]\nmirror_tilt_deg = {{ uniform = 0.2 }}\n[{table}]\nnear_mm = {front}\n")
    out = tmp_path / "study"
    code, _, err = run(capsys, "montecarlo", "--rig", "default", "--tolerances", str(tol), "-n", "1", "--workers",
                       "1", "-o", str(out))
    assert code == 2 and len(err.strip().splitlines()) == 1 and not out.exists(), err
    assert f"the tolerances' {table}.near_mm {front:g} mm lies inside the rig: its mirrors reach Z = 44.0 mm" in err


def test_a_study_beyond_a_night_is_refused_before_any_work(capsys, tmp_path):
    """Issue 41: `montecarlo -n 1000000` started instead of saying what it costs. One sample's renders are
    estimated (the shipped tolerances: 16 card views of 640x480 at 2x2 samples a pixel), times n,
    over the workers: beyond 24 h it is refused, exit 2, one line, no folder. A thousand samples fit."""
    from psvs.simulate.render import render_seconds
    from psvs.study.montecarlo import check_study_time
    from psvs.study.sample import check_study
    from psvs.study.tolerances import load_tolerances
    rig = load_rig("default")
    sample_s = check_study(rig, load_tolerances("default"))
    assert sample_s == render_seconds(rig, 2, 16)
    out = tmp_path / "study"
    code, text, err = run(capsys, "montecarlo", "--rig", "default", "--tolerances", "default", "-n", "1000000",
                          "--workers", "2", "-o", str(out))
    days = 1e6 * sample_s / 2 / 86400
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert (f"-n 1000000 (1000000 samples, their renders about {sample_s:.3g} s each, on 2 worker(s)) takes about "
            f"{days:.3g} days, more than the 1 day limit; fewer samples, or more workers") in err
    assert not out.exists()
    check_study_time(1000, sample_s, 2)


def test_a_remote_study_is_estimated_once_and_counted_on_the_schedulers_workers(capsys, tmp_path, monkeypatch,
                                                                                  client):
    """With --scheduler the estimate is made once, before connecting (it ran twice), and its time is
    counted over the workers the scheduler has (this module's 2-worker cluster): 1e6 samples are refused
    after connecting, exit 2, no folder."""
    from psvs.study import montecarlo, sample
    calls = []
    real = montecarlo.check_study
    monkeypatch.setattr(montecarlo, "check_study", lambda *a: calls.append(1) or real(*a))
    monkeypatch.setattr(sample, "check_study", lambda *a: pytest.fail("estimated a second time"))
    out = tmp_path / "study"
    code, text, err = run(capsys, "montecarlo", "--rig", "default", "--tolerances", "default", "-n", "1000000",
                          "-o", str(out), "--scheduler", client.scheduler.address)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "on 2 worker(s)) takes about" in err and "more than the 1 day limit" in err, err
    assert calls == [1] and not out.exists()


@pytest.mark.slow
@pytest.mark.parametrize("presses", [1, 2])
def test_an_interrupted_study_leaves_nothing_in_tmpdir(tmp_path, presses):
    """Issue 41: a Ctrl-C'd montecarlo left its workers' render folders in TMPDIR. The workers render under
    one folder the command makes and removes at its end, whatever ends it: Ctrl-C once a sample is
    rendering, exit 130, and TMPDIR holds nothing of psvs. Ctrl-C pressed twice (0.3 s apart) is the same,
    in one line and a few seconds (it took 71 s and printed Dask's traceback: adversarial trial)."""
    import subprocess
    import sys
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = dict(os.environ, TMPDIR=str(tmp), PYTHONPATH=str(root / "src"))
    proc = subprocess.Popen([sys.executable, "-m", "psvs", "montecarlo", "--rig", "default", "--tolerances",
                             str(root / "examples" / "tolerances_small.toml"), "-n", "4", "--workers", "1",
                             "-o", str(tmp_path / "study")], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True, env=env)
    t0 = time.monotonic()
    while not list(tmp.glob("psvs-montecarlo-*/psvs-study-*")):       # a sample is rendering
        assert proc.poll() is None and time.monotonic() - t0 < 300, proc.stderr.read() if proc.poll() else "slow"
        time.sleep(0.1)
    proc.send_signal(signal.SIGINT)
    t_int = time.monotonic()
    if presses == 2:
        time.sleep(0.3)
        proc.send_signal(signal.SIGINT)
    err = proc.communicate(timeout=120)[1]
    assert proc.returncode == 130, err
    assert list(tmp.glob("psvs-*")) == []
    assert err.strip().splitlines()[-1] == "psvs montecarlo: interrupted" and "Traceback" not in err, err
    assert time.monotonic() - t_int < 30
