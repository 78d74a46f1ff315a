"""Work on a Dask cluster (psvs.cluster, docs/cluster.md), each figure measured once (a run takes minutes;
the case returns the same number to run.py's best-of-7):

- ``psvs batch disparity`` of a 100-frame 640x480 video (the textured scene, rendered once into out/bench/)
  on 2 local workers, against 100 separate ``psvs disparity`` calls on the same frames (PNG files), one
  after the other; both are whole command lines (a process each, as a user runs them). Issue 29 asks the
  batch in less than half the serial time, with the same maps (checked here byte for byte).
- Samples per hour of :data:`SAMPLE` (any pure callable of an integer key: a sample of the default
  Monte-Carlo study, psvs.study.run_sample, or the one-second stand-in :func:`fig9_sample`), reported as
  seconds per sample, and each worker's peak memory (printed: maximum resident set size): on 1 worker held to
  one core, on 2 workers on two cores (the scaling with the cluster's size: near-linear means twice the
  rate), and on 1 worker free to use both cores (what one worker gets here: a sample's rendering uses every
  core, its calibration one).

Run it on a small input: ``python bench/bench_cluster.py 10 2`` (10 frames, 2 samples).
"""
from __future__ import annotations

import contextlib
import functools
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "out" / "bench"
FRAMES, SAMPLES = 100, 12
_done: dict = {}


def fig9_sample(key: int) -> dict:
    """The stand-in Monte-Carlo sample: the Fig. 9 pattern at 450-1050 mm (by key) rendered through the
    default rig with sensor noise seeded by the key, measured; the depth error."""
    from psvs.accuracy.pattern_measure import measure_pattern
    from psvs.io.params import load_rig
    from psvs.simulate.builtin import builtin_scene
    from psvs.simulate.render import render
    z = 450.0 + 40.0 * (key % 16)
    rig = load_rig("default")
    image = render(builtin_scene(f"fig9:distance_mm={z:g}"), rig, seed=key).image
    m = measure_pattern(image, rig, model="exact")
    return {"z_true_mm": z, "z_error_mm": m.Z_mm - z}


def study_sample(index: int) -> dict:
    """Sample ``index`` of the shipped default study (psvs.study.run_sample: the default rig, its
    tolerances, 16 card views, calibrated and scored; tens of seconds), seeded 2026 as bench_study's."""
    from psvs.io.params import load_rig
    from psvs.study.sample import run_sample
    from psvs.study.tolerances import load_tolerances
    return run_sample(load_rig("default"), load_tolerances("default"), 2026, index)


#: The callable the samples-per-hour cases time: a Monte-Carlo sample of ``psvs montecarlo``'s engine
#: (:func:`fig9_sample` is a one-second stand-in).
SAMPLE = study_sample


def _psvs(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "psvs", *args], check=True, cwd=ROOT, capture_output=True)


def _video(frames: int) -> tuple[Path, list[Path]]:
    """The textured scene moving 300 mm toward the rig over ``frames`` frames (FFV1), and its frames as PNG."""
    video = OUT / f"textured_{frames}.avi"
    pngs = OUT / f"textured_{frames}_frames"
    if not video.is_file() or not pngs.is_dir():
        OUT.mkdir(parents=True, exist_ok=True)
        _psvs("simulate", "textured", "--rig", "default", "--frames", str(frames), "--move-mm", "0,0,-300",
              "--supersample", "1", "-o", str(video))
        from psvs.io.images import write_png
        from psvs.live.source import open_video
        pngs.mkdir(exist_ok=True)
        with open_video(str(video)) as source:
            for i, frame in enumerate(source):
                write_png(pngs / f"frame_{i:06d}.png", frame)
    return video, sorted(pngs.glob("*.png"))


def batch_vs_serial(frames: int = FRAMES, workers: int = 2) -> dict:
    """Seconds of ``psvs batch disparity`` over the video on ``workers`` local workers and of one ``psvs
    disparity`` call per frame, one after the other; the maps checked identical."""
    video, pngs = _video(frames)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        _psvs("batch", "disparity", str(video), "--rig", "default", "-o", f"{tmp}/batch", "--workers", str(workers))
        batch_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        for png in pngs:
            _psvs("disparity", str(png), "--rig", "default", "-o", f"{tmp}/{png.stem}.npy")
        serial_s = time.perf_counter() - t0
        same = all(Path(tmp, "batch", p.stem + ".npy").read_bytes() == Path(tmp, p.stem + ".npy").read_bytes()
                   for p in pngs)
    if not same:
        raise AssertionError("psvs batch disparity's maps differ from psvs disparity's")
    print(f"batch disparity, {frames} frames: {batch_s:.1f} s on {workers} workers, {serial_s:.1f} s serially "
          f"({batch_s / serial_s:.2f} of it); maps identical", flush=True)
    return {"batch_s": batch_s, "serial_s": serial_s}


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0     # KiB on Linux


@contextlib.contextmanager
def _on_cores(n: int | None):
    """Within the block this process, and the worker processes it starts, run on its first ``n`` cores
    (None: all it may use)."""
    allowed = os.sched_getaffinity(0)
    if n is not None:
        os.sched_setaffinity(0, sorted(allowed)[:n])
    try:
        yield
    finally:
        os.sched_setaffinity(0, allowed)


def samples_per_hour(workers: int, n: int = SAMPLES, fn=None, cores: int | None = None) -> dict:
    """Samples per hour of ``fn`` (default :data:`SAMPLE`) over ``n`` keys on a new local cluster of
    ``workers`` (its start-up not counted) held to ``cores`` cores (None: all), and each worker's peak
    resident memory, MB."""
    from psvs.cluster import RunOptions, connect, run_tasks, task_threads
    fn = fn or SAMPLE
    with _on_cores(cores), connect(workers=workers) as client, tempfile.TemporaryDirectory() as tmp:
        client.run(_peak_rss_mb)                     # workers up
        t0 = time.perf_counter()
        summary = run_tasks(client, fn, range(n), Path(tmp) / "run", {"bench": fn.__name__},
                            RunOptions(progress=False, threads=task_threads(client)))
        wall = time.perf_counter() - t0
        memory = sorted(client.run(_peak_rss_mb).values())
    if not summary.complete:
        raise AssertionError(f"samples failed: {summary.failed}")
    rate = 3600.0 * n / wall
    on = f"{cores} core(s)" if cores else "every core"
    print(f"{fn.__name__} on {workers} worker(s), {on}: {rate:.0f} samples/h ({wall / n:.2f} s a sample), peak memory "
          f"per worker {', '.join(f'{m:.0f}' for m in memory)} MB", flush=True)
    return {"s_per_sample": wall / n, "rate_per_h": rate, "memory_mb": memory}


def _once(key: str, measure, field: str):
    """A case's function: measures once (minutes), then returns that figure to every later call."""
    def setup():
        def fn() -> float:
            if key not in _done:
                _done[key] = measure()
            return float(_done[key][field])
        return fn
    return setup


def cases():
    inf = float("inf")
    pair = functools.partial(batch_vs_serial, FRAMES, 2)
    return [
        (f"psvs batch disparity, {FRAMES}-frame 640x480 video, 2 local workers (whole command, measured once)",
         _once("pair", pair, "batch_s"), inf),
        (f"{FRAMES} psvs disparity calls on its frames, one after the other (measured once)",
         _once("pair", pair, "serial_s"), inf),
        (f"{SAMPLE.__name__}: seconds per sample on 1 local worker held to 1 core ({SAMPLES} samples, measured "
         "once)", _once("one", functools.partial(samples_per_hour, 1, cores=1), "s_per_sample"), inf),
        (f"{SAMPLE.__name__}: seconds per sample on 2 local workers, 2 cores ({SAMPLES} samples, measured once)",
         _once("two", functools.partial(samples_per_hour, 2), "s_per_sample"), inf),
        (f"{SAMPLE.__name__}: seconds per sample on 1 local worker free to use 2 cores ({SAMPLES} samples, "
         "measured once)", _once("one_free", functools.partial(samples_per_hour, 1), "s_per_sample"), inf),
    ]


if __name__ == "__main__":
    frames, samples = (int(a) for a in (sys.argv[1:] + ["10", "2"])[:2])
    if frames:
        batch_vs_serial(frames, 2)
    samples_per_hour(1, samples, cores=1)
    samples_per_hour(2, samples)
    samples_per_hour(1, samples)
