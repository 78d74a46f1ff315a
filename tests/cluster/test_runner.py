"""psvs.cluster on a real 2-worker LocalCluster (one per module: it starts in seconds): results equal the
serial ones, a killed worker loses nothing finished, a finished run computes nothing, an interrupted one
resumes with only the rest, and an unreachable scheduler is one line with nothing written."""
import functools
import os
import signal
import socket
import threading
import time

import pyarrow.parquet as pq
import pytest

from psvs.cluster import RunOptions, connect, read_results, run_tasks
from psvs.cluster.client import scheduler_address
from tests.cluster.tasks import counted, fails_on, not_a_row, sample

QUIET = RunOptions(progress=False)


@pytest.fixture(scope="module")
def client():
    with connect(workers=2) as c:
        yield c


def _calls(folder) -> list[int]:
    return sorted(int(p.name.split("-")[0]) for p in folder.iterdir())


def _rows(out_dir) -> dict:
    table = read_results(out_dir).to_pylist()
    return {r["key"]: {k: v for k, v in r.items() if k not in ("key", "pid")} for r in table}


def test_results_equal_the_serial_run_and_use_both_workers(client, tmp_path):
    calls = tmp_path / "calls"
    calls.mkdir()
    keys = list(range(12))
    s = run_tasks(client, functools.partial(counted, str(calls), 0.2), keys, tmp_path / "run", {"seed": 7}, QUIET)
    assert (s.total, s.skipped, s.computed, s.failed) == (12, 0, 12, {}) and s.complete
    assert _rows(tmp_path / "run") == {k: sample(k) for k in keys}       # exactly, floats included
    assert len(set(read_results(tmp_path / "run").column("pid").to_pylist())) == 2
    assert (tmp_path / "run" / "results.parquet").is_file() and not (tmp_path / "run" / "parts").exists()


def test_a_second_run_over_a_finished_folder_computes_nothing(client, tmp_path):
    calls = tmp_path / "calls"
    calls.mkdir()
    fn = functools.partial(counted, str(calls), 0.0)
    run_tasks(client, fn, range(6), tmp_path / "run", {"seed": 7}, QUIET)
    before = (tmp_path / "run" / "results.parquet").read_bytes()
    s = run_tasks(client, fn, range(6), tmp_path / "run", {"seed": 7}, QUIET)
    assert (s.total, s.skipped, s.computed) == (6, 6, 0)
    assert _calls(calls) == list(range(6))                     # no task ran a second time
    assert (tmp_path / "run" / "results.parquet").read_bytes() == before


def test_an_interrupted_run_resumes_with_only_the_rest(client, tmp_path):
    """Stopped part-way (here: run over the first 5 keys), the full run computes only the other 7, and the
    rows are what one run gives."""
    calls = tmp_path / "calls"
    calls.mkdir()
    fn = functools.partial(counted, str(calls), 0.0)
    first = run_tasks(client, fn, range(5), tmp_path / "run", {"seed": 7}, QUIET)
    assert first.computed == 5
    s = run_tasks(client, fn, range(12), tmp_path / "run", {"seed": 7}, QUIET)
    assert (s.skipped, s.computed) == (5, 7)
    assert _calls(calls) == list(range(12))
    assert _rows(tmp_path / "run") == {k: sample(k) for k in range(12)}


def test_ctrl_c_keeps_every_result_written_and_the_rerun_finishes(client, tmp_path):
    """A KeyboardInterrupt in the middle (raised in the caller's thread while tasks run): what was written
    stays, the rest is cancelled, and the next run computes only what is missing."""
    calls = tmp_path / "calls"
    calls.mkdir()
    fn = functools.partial(counted, str(calls), 0.3)
    out = tmp_path / "run"
    timer = threading.Timer(1.5, lambda: signal.pthread_kill(threading.main_thread().ident, signal.SIGINT))
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        run_tasks(client, fn, range(20), out, {"seed": 7}, QUIET)
    timer.cancel()
    written = _rows(out)
    assert 0 < len(written) < 20
    s = run_tasks(client, fn, range(20), out, {"seed": 7}, QUIET)
    assert s.skipped == len(written) and s.computed == 20 - len(written)
    assert _rows(out) == {k: sample(k) for k in range(20)}


def _part_rows(out_dir) -> dict:
    rows = {}
    for part in sorted((out_dir / "parts").glob("part-*.parquet")) if (out_dir / "parts").is_dir() else []:
        for r in pq.read_table(part).to_pylist():
            rows[r["key"]] = r
    return rows


def test_a_killed_worker_loses_no_finished_result_and_the_run_completes(client, tmp_path):
    """One worker process is killed (SIGKILL) once results have been written: those stay as written, the
    tasks it was running are run again (distributed reschedules them; its nanny restarts it), and the run
    completes with every result equal to the serial one."""
    calls = tmp_path / "calls"
    calls.mkdir()
    out = tmp_path / "run"
    result = {}
    worker = threading.Thread(target=lambda: result.update(s=run_tasks(
        client, functools.partial(counted, str(calls), 0.4), range(16), out, {"seed": 7}, QUIET)))
    worker.start()
    t0 = time.monotonic()
    while not _part_rows(out) and time.monotonic() - t0 < 60:
        time.sleep(0.05)
    finished = _part_rows(out)
    assert finished, "no result within 60 s"
    pids = client.run(os.getpid)
    os.kill(next(iter(pids.values())), signal.SIGKILL)
    worker.join(timeout=120)
    assert not worker.is_alive()
    s = result["s"]
    assert s.complete and s.failed == {} and s.computed == 16
    table = {r["key"]: r for r in read_results(out).to_pylist()}
    assert all(table[k] == r for k, r in finished.items())       # the rows written before the kill, as they were
    assert _rows(out) == {k: sample(k) for k in range(16)}
    assert len(_calls(calls)) >= 16
    client.wait_for_workers(2, timeout=60)                       # the nanny brought it back
    assert set(client.run(os.getpid).values()) != set(pids.values())


def test_a_task_that_raises_is_reported_not_written_and_retried_next_time(client, tmp_path):
    s = run_tasks(client, functools.partial(fails_on, 3), range(6), tmp_path / "run", {}, RunOptions(retries=1,
                                                                                                    progress=False))
    assert s.computed == 5 and not s.complete
    assert s.failed == {3: "RuntimeError: sample 3 cannot be drawn"}
    assert sorted(_rows(tmp_path / "run")) == [0, 1, 2, 4, 5]
    s = run_tasks(client, sample, range(6), tmp_path / "run", {}, QUIET)
    assert (s.skipped, s.computed) == (5, 1) and s.complete


def test_a_result_that_is_not_a_row_of_scalars_is_a_failure(client, tmp_path):
    s = run_tasks(client, not_a_row, [1], tmp_path / "run", {}, RunOptions(retries=0, progress=False))
    assert s.computed == 0 and "array is a ndarray, not a scalar" in s.failed[1]


def test_a_folder_made_with_other_parameters_is_refused(client, tmp_path):
    run_tasks(client, sample, range(3), tmp_path / "run", {"seed": 7, "n": 3}, QUIET)
    before = {p.name: p.read_bytes() for p in (tmp_path / "run").iterdir()}
    with pytest.raises(ValueError, match=r"other parameters \(seed: 7 there, 8 now\)") as e:
        run_tasks(client, sample, range(3), tmp_path / "run", {"seed": 8, "n": 3}, QUIET)
    assert "\n" not in str(e.value)
    assert {p.name: p.read_bytes() for p in (tmp_path / "run").iterdir()} == before


def test_keys_are_checked(client, tmp_path):
    with pytest.raises(ValueError, match="distinct"):
        run_tasks(client, sample, [1, 1], tmp_path / "run", {}, QUIET)
    with pytest.raises(TypeError, match="strings or integers"):
        run_tasks(client, sample, [1.5], tmp_path / "run", {}, QUIET)
    assert not (tmp_path / "run").exists()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_an_unreachable_scheduler_is_one_line_quickly(tmp_path):
    address = f"tcp://127.0.0.1:{_free_port()}"
    t0 = time.monotonic()
    with pytest.raises(ValueError, match="cannot reach the Dask scheduler at " + address) as e:
        connect(address, timeout_s=2.0)
    assert time.monotonic() - t0 < 10 and "\n" not in str(e.value)


@pytest.mark.parametrize("text", ["localhost", "tcp://host", "http://host:8786", "host:99999", "a b:1"])
def test_a_scheduler_address_that_is_not_one(text):
    with pytest.raises(ValueError, match="--scheduler must be tcp://HOST:PORT"):
        scheduler_address(text)


def test_workers_are_for_a_local_cluster_only():
    with pytest.raises(ValueError, match="--workers sets a local cluster"):
        connect("tcp://127.0.0.1:8786", workers=2)
    with pytest.raises(ValueError, match="--workers must be 1-512"):
        connect(None, workers=0)


def test_a_local_clusters_tasks_share_the_cores(client, tmp_path):
    """Two workers on this machine's cores: each task's Numba loops get its share (at least one thread), not a
    thread per core each."""
    from psvs.cluster import local_workers, task_threads
    from tests.cluster.tasks import numba_threads
    share = task_threads(client)
    assert share == max(1, local_workers() // 2)
    run_tasks(client, numba_threads, range(4), tmp_path / "run", {}, RunOptions(progress=False, threads=share))
    assert {r["threads"] for r in read_results(tmp_path / "run").to_pylist()} == {share}


def test_a_local_clusters_blas_pools_get_the_share_and_the_rest_of_the_environment_is_ours(tmp_path, monkeypatch):
    """Each local worker's OpenBLAS/MKL pool is held to its share of the cores (their idle threads spin and took
    the other worker's core) unless this process's environment sets it (Dask's rule: the user's word wins);
    OMP_NUM_THREADS and glibc's trim threshold stay as in this process."""
    from psvs.cluster import local_workers
    from tests.cluster.tasks import environ
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    monkeypatch.setenv("MKL_NUM_THREADS", "97")
    monkeypatch.setenv("OMP_NUM_THREADS", "5")
    monkeypatch.delenv("MALLOC_TRIM_THRESHOLD_", raising=False)
    with connect(workers=1) as one:
        run_tasks(one, environ, range(2), tmp_path / "run", {}, QUIET)
    rows = [{k: v for k, v in r.items() if k != "key"} for r in read_results(tmp_path / "run").to_pylist()]
    assert rows == [{"OPENBLAS_NUM_THREADS": str(local_workers()), "MKL_NUM_THREADS": "97", "OMP_NUM_THREADS": "5",
                     "MALLOC_TRIM_THRESHOLD_": "unset"}] * 2


def test_the_blas_share_is_the_cores_over_the_workers(monkeypatch):
    import psvs.cluster.client as cc
    monkeypatch.setattr(cc, "local_workers", lambda: 8)
    assert cc.blas_environ(2) == {"OPENBLAS_NUM_THREADS": "4", "MKL_NUM_THREADS": "4"}
    assert cc.blas_environ(3) == {"OPENBLAS_NUM_THREADS": "2", "MKL_NUM_THREADS": "2"}
    assert cc.blas_environ(16) == {"OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def test_an_existing_scheduler_with_a_worker_of_its_own(tmp_path):
    """``dask scheduler`` and ``dask worker tcp://...`` started as a user starts them on other machines: the
    run goes through them, with the results of the serial run."""
    import subprocess
    import sys
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(root / "src"), str(root)]))
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--port", str(port),
                               "--dashboard-address", ":0"], cwd=root, env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)]
    try:
        procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address, "--nworkers",
                                       "1", "--nthreads", "1"], cwd=root, env=env, stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL))
        t0 = time.monotonic()
        while True:
            try:
                client = connect(address, timeout_s=2.0)
                break
            except ValueError:
                assert time.monotonic() - t0 < 60, "the scheduler did not start within 60 s"
        with client:
            client.wait_for_workers(1, timeout=60)
            s = run_tasks(client, sample, range(5), tmp_path / "run", {"seed": 7}, QUIET)
        assert s.computed == 5 and _rows(tmp_path / "run") == {k: sample(k) for k in range(5)}
    finally:
        for p in reversed(procs):
            p.terminate()
            p.wait(timeout=30)


def test_a_local_cluster_leaves_nothing_in_the_temporary_folder(tmp_path, monkeypatch):
    """A local cluster's workers keep their scratch space in a folder of the run's own, which goes when the
    client closes: nothing is left in TMPDIR (Dask's default left dask-scratch-space and its lock files)."""
    import tempfile
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    with connect(workers=1) as one:
        assert [p.name[:10] for p in tmp.iterdir()] == ["psvs-dask-"]
        run_tasks(one, sample, range(2), tmp_path / "run", {}, QUIET)
    assert list(tmp.iterdir()) == []
