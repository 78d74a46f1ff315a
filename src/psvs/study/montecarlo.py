"""A Monte-Carlo study on Dask: :func:`psvs.study.sample.run_sample` for samples 0 .. n-1 as tasks
(:func:`psvs.cluster.run_tasks`), their rows streamed to Parquet in the study's folder, then the report
(:func:`psvs.study.report.write_report`). A sample is seeded from (seed, index), so a row does not depend on
the worker that ran it; a study resumes where it stopped, and a larger ``n`` over a finished folder computes
only the new samples (docs/tolerancing.md)."""
from __future__ import annotations

import functools
from dataclasses import dataclass

from psvs._budget import check_time, duration
from psvs.cluster import RunOptions, read_results, run_tasks
from psvs.cluster.store import check_params, check_run_folder
from psvs.io.params import rig_to_dict
from psvs.optics.rig import Rig
from psvs.study.report import write_report
from psvs.study.sample import check_study, run_sample
from psvs.study.tolerances import Tolerances

#: The most samples one study may ask for.
MAX_SAMPLES = 1_000_000
#: s: the longest a study may keep its workers busy (one night): a larger study is split, or given more workers.
STUDY_LIMIT_S = 24 * 3600.0


@dataclass(frozen=True)
class StudyResult:
    """``summary``: the run (:class:`psvs.cluster.RunSummary`); ``rows``: every sample's row in the folder
    (this run's and earlier ones'), by index; ``files``: the report's files."""

    summary: object
    rows: list
    files: list


def study_params(nominal: Rig, tol_data: dict, seed: int) -> dict:
    """What makes a study's rows what they are (recorded in the folder's study.json): the nominal rig, the
    tolerance file's content and the seed; not the number of samples (a larger -n adds samples)."""
    return {"study": "psvs montecarlo", "seed": int(seed), "rig": rig_to_dict(nominal), "tolerances": tol_data}


def check_samples(n: int, seed: int) -> None:
    """ValueError naming the option when ``-n`` is outside 1..:data:`MAX_SAMPLES` or ``--seed`` outside
    [0, 2^63)."""
    if not 1 <= n <= MAX_SAMPLES:
        raise ValueError(f"-n must be 1-{MAX_SAMPLES}, got {n}")
    if not 0 <= seed < 2 ** 63:
        raise ValueError(f"--seed must be an integer in [0, 2^63), got {seed}")


def check_study_time(n: int, sample_s: float, workers: int) -> None:
    """ValueError when ``n`` samples whose renders take ``sample_s`` s each would keep ``workers`` workers
    busy beyond :data:`STUDY_LIMIT_S` (renders alone: calibrating adds to it)."""
    check_time(n * sample_s / max(1, workers), f"-n {n} ({n} samples, their renders about {duration(sample_s)} "
               f"each, on {workers} worker(s))", "fewer samples, or more workers "
               "(--workers, or a larger cluster through --scheduler)", limit_s=STUDY_LIMIT_S)


def prepare_study(nominal: Rig, tol: Tolerances, tol_data: dict, n: int, seed: int, out_dir,
                  workers: int | None = None) -> tuple[dict, float]:
    """Every check before a cluster starts: the counts, the study the nominal design can run at all
    (:func:`check_study`), its time on ``workers`` workers when known (:func:`check_study_time`; a remote
    cluster's are counted once it is reached, from the same one-sample estimate), the folder (a file, a
    missing parent, another study's folder: ValueError). (the study's parameters, one sample's estimated
    render seconds)."""
    check_samples(n, seed)
    sample_s = check_study(nominal, tol)
    if workers is not None:
        check_study_time(n, sample_s, workers)
    out = check_run_folder(out_dir, "psvs montecarlo")
    params = study_params(nominal, tol_data, seed)
    if out.is_dir():
        check_params(out, params)
    return params, sample_s


def run_study(client, nominal: Rig, tol: Tolerances, n: int, out_dir, params: dict,
              options: RunOptions = RunOptions(label="psvs montecarlo")) -> StudyResult:
    """Samples 0 .. n-1 of the study on ``client`` (those already in ``out_dir`` are not computed again),
    then the report over every sample in the folder up to n-1."""
    fn = functools.partial(run_sample, nominal, tol, int(params["seed"]))
    summary = run_tasks(client, fn, range(n), out_dir, params, options)
    table = read_results(out_dir)
    rows = [r for r in table.to_pylist() if r["key"] < n]
    for r in rows:
        r.pop("key")
    files = write_report(rows, out_dir, tol.targets) if rows else []
    return StudyResult(summary, rows, files)
