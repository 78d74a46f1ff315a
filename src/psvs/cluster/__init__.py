"""Work spread over a Dask cluster: a client on this machine's cores or on an existing scheduler
(:func:`connect`), and a resumable runner that streams each finished result into Parquet (:func:`run_tasks`,
:func:`read_results`). Used by ``psvs batch`` and ``psvs montecarlo``; see docs/cluster.md."""
import lazy_loader as _lazy

# The package's public face: what other packages and users may import from it. Each name is loaded on
# first use (scikit-image's lazy_loader), so importing the package loads none of its modules.
__getattr__, __dir__, __all__ = _lazy.attach(
    __name__,
    submodules=[],
    submod_attrs={
        "client": ["connect", "local_workers", "task_threads"],
        "runner": ["RunOptions", "RunSummary", "run_tasks"],
        "store": ["ResultStore", "check_params", "check_run_folder", "read_results"],
    },
)
