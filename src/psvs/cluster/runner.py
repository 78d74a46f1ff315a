"""Run ``fn(key)`` for every key on a Dask client, resumably: what is already in the run's folder is not
computed again, and each batch of results is written to Parquet as it finishes (:mod:`psvs.cluster.store`).

``fn`` must be pure in its key (e.g. a Monte-Carlo sample seeded from (seed, index), or a frame's result
computed from the frame): then a result does not depend on the worker that ran it, a task lost with its worker
is simply run again elsewhere (distributed reschedules it), and a resumed run gives what one run would."""
from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field
from pathlib import Path

from psvs._threads import thread_share
from psvs.cluster.progress import Progress
from psvs.cluster.store import ResultStore, check_row, record_params


@dataclass(frozen=True)
class RunOptions:
    """How :func:`run_tasks` runs.

    retries : times a task that raised is run again before it counts as failed (a task whose worker died is
        rescheduled by distributed whatever this says, up to its ``allowed-failures``).
    progress : a progress bar on stderr (redrawn on a terminal, plain lines in a log; False: none).
    label : the progress bar's name.
    compact_every : part files after which they are merged into results.parquet during a run.
    threads : Numba threads a task runs its parallel loops on (``numba.set_num_threads`` in the task's thread;
        None: the worker's default, every core). :func:`psvs.cluster.client.task_threads` gives a local
        cluster's share. It changes no result psvs computes, only the time (tests/cli/test_batch_cli.py).
    """

    retries: int = 2
    progress: bool = True
    label: str = "tasks"
    compact_every: int = 256
    threads: int | None = None

    def __post_init__(self):
        if not 0 <= self.retries <= 10:
            raise ValueError(f"retries must be 0-10, got {self.retries}")


@dataclass(frozen=True)
class RunSummary:
    """What a run did: ``total`` keys asked for, ``skipped`` already done before it, ``computed`` finished and
    written by it, ``failed`` {key: one-line reason} of tasks that raised (not written: a later run tries them
    again)."""

    total: int
    skipped: int
    computed: int
    failed: dict = field(default_factory=dict)

    @property
    def complete(self) -> bool:
        return self.skipped + self.computed == self.total


def _task(fn, threads, key):
    """What a worker runs: ``fn(key)`` (on ``threads`` Numba threads when not None) checked to be a flat row of
    scalars, with its key."""
    if threads is not None:
        import numba
        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    with thread_share(threads):          # the renderer's and Embree's pools too
        return check_row(fn(key), key)


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return f"{type(exc).__name__}: {text.splitlines()[0]}" if text else type(exc).__name__


def _keys(keys) -> list:
    keys = list(keys)
    bad = next((k for k in keys if not isinstance(k, (str, int)) or isinstance(k, bool)), None)
    if bad is not None:
        raise TypeError(f"keys must be strings or integers, got {bad!r}")
    if len(set(keys)) != len(keys) or len({type(k) for k in keys}) > 1:
        raise ValueError("keys must be distinct and all of one type (strings or integers)")
    return keys


def run_tasks(client, fn, keys, out_dir, params: dict | None = None, options: RunOptions = RunOptions()):
    """Compute ``fn(key)`` (a flat dict of scalars) on ``client``'s workers for every key of ``keys`` not yet
    in ``out_dir``, writing each finished batch of rows to Parquet there as it arrives; a
    :class:`RunSummary`. Read the rows with :func:`psvs.cluster.read_results`.

    ``out_dir`` is created (its parent must exist); ``params`` (JSON-able: what makes a result what it is,
    not the keys) go to ``out_dir/study.json``, and a folder holding other parameters is refused (ValueError).
    A task that raises is retried ``options.retries`` times, then reported in ``failed`` and not written, and
    the run goes on. Ctrl-C (or any error) cancels what is still running; every result written stays."""
    keys = _keys(keys)
    out_dir = Path(out_dir)
    if not out_dir.parent.is_dir():
        raise FileNotFoundError(f"output folder's parent does not exist: {out_dir.parent}")
    if out_dir.exists() and not out_dir.is_dir():
        raise ValueError(f"output {out_dir} is a file, not a folder")
    out_dir.mkdir(exist_ok=True)
    record_params(out_dir, params or {})
    store = ResultStore(out_dir)
    done = store.done_keys()
    todo = [k for k in keys if k not in done]
    summary = _submit_and_collect(client, fn, todo, store, options, len(keys) - len(todo))
    if summary.complete or not todo:
        store.compact()
    return summary


def _submit_and_collect(client, fn, todo: list, store: ResultStore, options: RunOptions, skipped: int):
    """Submit ``todo``, write each batch of results as it completes; the :class:`RunSummary`."""
    if not todo:
        return RunSummary(skipped, skipped, 0)
    from distributed import as_completed
    bar = Progress(options.label, len(todo), skipped) if options.progress else None
    tag = f"psvs-{time.time_ns():x}"     # task names unique to this run (a client may run several)
    names = {f"{tag}-{i}": k for i, k in enumerate(todo)}
    futures = client.map(functools.partial(_task, fn, options.threads), todo, key=list(names),
                         retries=options.retries, pure=False)
    computed, failed, parts = 0, {}, 0
    pending = set(futures)
    try:
        for batch in as_completed(futures, loop=client.loop, raise_errors=False).batches():
            rows = []
            for fut in batch:
                pending.discard(fut)
                if fut.status == "finished":
                    rows.append(fut.result())
                else:
                    failed[names[fut.key]] = _reason(fut)
                fut.release()
            store.append(rows)
            computed, parts = computed + len(rows), parts + bool(rows)
            if parts >= options.compact_every:
                store.compact()
                parts = 0
            if bar is not None:
                bar.update(len(rows), len(batch) - len(rows))
    finally:
        if pending:
            client.cancel(list(pending))
        if bar is not None:
            bar.close()
    return RunSummary(skipped + len(todo), skipped, computed, failed)


def _reason(fut) -> str:
    """One line saying why a future did not finish."""
    try:
        exc = fut.exception()
    except BaseException as why:      # cancelled: the scheduler dropped it
        exc = why
    return _one_line(exc) if exc is not None else fut.status
