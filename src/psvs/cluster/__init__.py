"""Work spread over a Dask cluster: a client on this machine's cores or on an existing scheduler
(:func:`connect`), and a resumable runner that streams each finished result into Parquet (:func:`run_tasks`,
:func:`read_results`). Used by ``psvs batch`` and ``psvs montecarlo``; see docs/cluster.md."""
from psvs.cluster.client import connect, local_workers, task_threads
from psvs.cluster.runner import RunOptions, RunSummary, run_tasks
from psvs.cluster.store import read_results

__all__ = ["connect", "local_workers", "task_threads", "run_tasks", "RunOptions", "RunSummary", "read_results"]
