"""A ``dask.distributed`` client: a LocalCluster on this machine's cores (processes, one thread each), or an
existing scheduler that other machines' workers joined (``tcp://HOST:8786``, docs/cluster.md)."""
from __future__ import annotations

import logging
import os
import re
import shutil
import signal
import tempfile
import threading
import weakref

from distributed import Client
from distributed.diagnostics.plugin import WorkerPlugin

#: How long to wait for an existing scheduler to answer before saying it cannot be reached, s.
CONNECT_TIMEOUT_S = 5.0
#: The most workers a local cluster starts (a bound on a mistyped --workers, far above any one machine).
MAX_LOCAL_WORKERS = 512
_ADDRESS = re.compile(r"^(?:(tcp|tls)://)?(\[[0-9a-fA-F:.]+\]|[A-Za-z0-9_.-]+):(\d{1,5})$")


def local_workers() -> int:
    """The cores this process may run on: the default worker count of a local cluster."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def core_share(workers: int) -> int:
    """The threads each of ``workers`` local workers may use: this machine's cores shared among them, at
    least 1."""
    return max(1, local_workers() // max(1, workers))


def scheduler_address(text: str) -> str:
    """``HOST:PORT`` or ``tcp://HOST:PORT`` (or ``tls://``) as a scheduler address; ValueError when it is not
    one.

    >>> scheduler_address("10.0.0.5:8786")
    'tcp://10.0.0.5:8786'
    """
    m = _ADDRESS.match(text.strip())
    if m is None or not 1 <= int(m.group(3)) <= 65535:
        raise ValueError(f"--scheduler must be tcp://HOST:PORT (e.g. tcp://10.0.0.5:8786), got {text!r}")
    return f"{m.group(1) or 'tcp'}://{m.group(2)}:{int(m.group(3))}"


def connect(scheduler: str | None = None, workers: int | None = None, timeout_s: float = CONNECT_TIMEOUT_S):
    """A ``distributed.Client``: on the scheduler at ``scheduler`` (its workers are its own), or, when None, on
    a new LocalCluster of ``workers`` processes (default :func:`local_workers`) with one thread each, its logs
    at CRITICAL only (a task's error reaches the caller as its exception; after Ctrl-C a worker's heartbeat to
    the closed scheduler logs an ERROR traceback, which is no news to the user) and no dashboard. Close it
    (``with connect(...) as client:``): a local cluster closes with it.

    An address that is not one, or a scheduler that does not answer within ``timeout_s``, is a one-line
    ValueError; nothing is started or written."""
    if scheduler is not None and workers is not None:
        raise ValueError("--workers sets a local cluster's size; the workers of --scheduler are those started "
                         "for it (dask worker tcp://HOST:PORT, docs/cluster.md)")
    if workers is not None and not 1 <= workers <= MAX_LOCAL_WORKERS:
        raise ValueError(f"--workers must be 1-{MAX_LOCAL_WORKERS}, got {workers}")
    import dask
    if scheduler is None:
        n = workers or local_workers()
        # the workers' scratch space in a folder of this run's own, removed with the client (Dask's default,
        # TMPDIR/dask-scratch-space, outlives the run with its lock files)
        scratch = tempfile.mkdtemp(prefix="psvs-dask-")
        try:
            with dask.config.set({"distributed.nanny.pre-spawn-environ": blas_environ(n),
                                  "temporary-directory": scratch}):
                client = _LocalClient(n_workers=n, threads_per_worker=1, processes=True,
                                      dashboard_address=":0", scheduler_kwargs={"dashboard": False},
                                      silence_logs=logging.CRITICAL, set_as_default=False)
        except BaseException:
            shutil.rmtree(scratch, ignore_errors=True)
            raise
        # removed when the client closes, or at exit for a client never closed
        client.remove_scratch = weakref.finalize(client, shutil.rmtree, scratch, True)
        client.register_plugin(_IgnoreInterrupt())
        client.interrupt_once()
        return client
    address = scheduler_address(scheduler)
    try:
        return Client(address, timeout=timeout_s, set_as_default=False)
    except Exception as exc:   # OSError (refused, timed out), or whatever a non-Dask server's reply raises
        text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ValueError(f"cannot reach the Dask scheduler at {address}: {text[:200]}") from None


class _LocalClient(Client):
    """A client of a local cluster whose workers' scratch folder goes when it closes (``remove_scratch``: a
    finalizer, which runs once)."""

    remove_scratch = None
    sigint_before = None
    _closing = False

    def close(self, *args, **kwargs):
        """Close the client and its local cluster, then remove the workers' scratch folder; once (a second
        call, as the garbage collector's, does nothing), and not cut short by a second Ctrl-C (ignored for
        the close: cut, it left the cluster half closed, and the collector's close then waited 60 s and
        printed Dask's traceback)."""
        if self._closing:
            return None
        self._closing = True
        main = threading.current_thread() is threading.main_thread()
        now = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
        try:
            return super().close(*args, **kwargs)
        finally:
            if main:
                signal.signal(signal.SIGINT, self.sigint_before if self.sigint_before is not None else now)
            if self.remove_scratch is not None:
                self.remove_scratch()

    def interrupt_once(self) -> None:
        """While the cluster runs (main thread only): the first Ctrl-C interrupts as usual, and the ones after
        it are ignored until the cluster is closed, so that the unwinding and the close are not cut short
        (a second Ctrl-C 0.3 s after the first raised inside Dask's garbage-collector callback)."""
        if threading.current_thread() is not threading.main_thread():
            return
        def once(signum, frame):
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            raise KeyboardInterrupt
        self.sigint_before = signal.signal(signal.SIGINT, once)


class _IgnoreInterrupt(WorkerPlugin):
    """Ctrl-C in the terminal reaches the local workers too (one process group): they ignore it (each would
    print a traceback), and the client that started them stops the run and closes them."""

    name = "psvs-ignore-interrupt"

    def setup(self, worker):
        logging.getLogger("distributed").setLevel(logging.CRITICAL)
        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, signal.SIG_IGN)


def blas_environ(workers: int) -> dict:
    """The environment a local cluster's ``workers`` start with besides this process's: their BLAS pools
    (OpenBLAS, MKL) held to :func:`local_workers` shared among them, as Dask's default holds them to one. A
    variable set in this process's environment wins (Dask's rule: ``OPENBLAS_NUM_THREADS=4 psvs montecarlo``).

    An idle OpenBLAS thread spins for a while after each call: two workers' spinning threads took the core the
    other worker's calibration ran on, and 2 workers gave 1.2 times the study samples an hour of one, 1.9 times
    once held (docs/cluster.md#speed). The rest of Dask's default is left out: MALLOC_TRIM_THRESHOLD_ (glibc then
    returns every freed array to the system: a dense disparity map took 2.5 times as long) and
    OMP_NUM_THREADS (Numba's loops get their share in the task, :func:`task_threads`).

    >>> blas_environ(local_workers())        # a worker per core: one BLAS thread each
    {'OPENBLAS_NUM_THREADS': '1', 'MKL_NUM_THREADS': '1'}
    """
    share = str(core_share(workers))
    return {"OPENBLAS_NUM_THREADS": share, "MKL_NUM_THREADS": share}


def task_threads(client) -> int | None:
    """The threads a task may use on ``client``'s workers: on a local cluster this machine's cores shared
    among its workers (at least 1), so that N workers of Numba's parallel loops do not each start a thread per
    core; None on an existing scheduler (its workers' own setting)."""
    cluster = getattr(client, "cluster", None)
    if cluster is None:
        return None
    return core_share(len(cluster.workers))
