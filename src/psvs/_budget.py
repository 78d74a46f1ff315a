"""Budgets checked before big work, so a command refuses in one line instead of running for hours or dying
for memory later.

- **Time.** A count a user types (frames, views, cycles) times the cost of one (a render, a control cycle) is
  the time the command would take; work estimated beyond :data:`WORK_LIMIT_S` is refused before it starts,
  saying the estimate and the limit (:func:`check_time`).
- **Memory.** An allocation plan beyond :data:`USABLE_SHARE` of the memory available now
  (:func:`available_bytes`: the system's figure, or ``$PSVS_MEMORY_AVAILABLE_MIB``) is refused before the
  allocation (:func:`check_memory`).
- **Pages.** psvs's commands keep NumPy from advising the kernel to back large arrays with huge pages
  (:func:`small_pages`): on a kernel that compacts memory to grant them, every fresh array paid for it.
"""
from __future__ import annotations

import os

#: Share of the memory available now that one allocation plan may use.
USABLE_SHARE = 0.8
#: Environment variable that states the memory psvs may take as available, in MiB, instead of the system's
#: figure: for a machine shared with other work, and for the tests (whose refusals must not depend on what
#: else the machine runs).
AVAILABLE_ENV = "PSVS_MEMORY_AVAILABLE_MIB"


def available_bytes() -> int:
    """Memory available to this process now, bytes: ``$PSVS_MEMORY_AVAILABLE_MIB`` when set, else (Linux)
    MemAvailable, else the physical memory."""
    stated = os.environ.get(AVAILABLE_ENV)
    if stated is not None:
        try:
            mib = float(stated)
        except ValueError:
            mib = -1.0
        if not mib > 0 or mib == float("inf"):
            raise ValueError(f"{AVAILABLE_ENV} must be a positive number of MiB, got {stated!r}")
        return int(mib * 1024 * 1024)
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):   # pragma: no cover - platforms without sysconf
        return 1 << 40


def human(n: float) -> str:
    """Bytes in binary units, e.g. ``2.2 TiB``."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if n < 1024 or unit == "PiB":
            return f"{n:.1f} {unit}" if unit != "B" else f"{n:.0f} B"
        n /= 1024
    raise AssertionError  # pragma: no cover


def check_memory(need_bytes: float, what: str, hint: str = "", limit_bytes: float | None = None) -> None:
    """ValueError naming ``what`` (the option the user typed) when ``need_bytes`` exceeds the usable memory.

    ``limit_bytes`` defaults to :data:`USABLE_SHARE` of :func:`available_bytes`; ``hint`` (e.g. the largest
    value that fits) is appended to the message."""
    limit = USABLE_SHARE * available_bytes() if limit_bytes is None else float(limit_bytes)
    if need_bytes > limit:
        tail = f"; {hint}" if hint else ""
        raise ValueError(f"{what} needs about {human(need_bytes)} of memory, more than the {human(limit)} "
                         f"available{tail}")


#: The longest a command may plan to work, s.
WORK_LIMIT_S = 3600.0


def duration(seconds: float) -> str:
    """Seconds in the largest fitting unit, e.g. ``45 s``, ``12.5 min``, ``34.1 h``, ``2.3e+04 days``."""
    for unit, size in (("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if seconds >= size:
            value = f"{seconds / size:.3g}"
            return f"{value} {'day' if unit == 'days' and value == '1' else unit}"
    return f"{seconds:.3g} s"


def check_time(seconds: float, what: str, hint: str = "", limit_s: float | None = None) -> None:
    """ValueError "<what> takes about <estimate>, more than the <limit> limit; <hint>" when ``seconds``
    exceeds ``limit_s`` (default :data:`WORK_LIMIT_S`). ``what`` names the options the user typed and how the
    estimate follows from them."""
    limit = WORK_LIMIT_S if limit_s is None else float(limit_s)
    if not seconds <= limit:   # NaN and inf too
        tail = f"; {hint}" if hint else ""
        raise ValueError(f"{what} takes about {duration(seconds)}, more than the {duration(limit)} limit{tail}")


#: The environment variable NumPy reads at import: 1 advises the kernel to back large arrays with transparent
#: huge pages (NumPy's default on Linux), 0 does not.
HUGEPAGE_ENV = "NUMPY_MADVISE_HUGEPAGE"


def small_pages() -> bool:
    """Turn NumPy's huge-page advice off in this process and the processes it starts (workers, subprocesses),
    unless the user set :data:`HUGEPAGE_ENV`; True when it was turned off here. Where the kernel grants huge
    pages only after compacting memory on the fault (``/sys/kernel/mm/transparent_hugepage/defrag`` at
    ``madvise``, a common default), each fresh large array waits for it, and a grant that fails is waited for
    all the same: on the 2-core EPYC the benchmarks run on, first touching a new array ran at 0.2-1.1 GB/s with
    the advice and 2.1-2.6 without, and ``psvs disparity --depth`` on the 1440x1080 build took 2.02-2.96 s
    (median 2.49) with it against 2.04-2.09 s (median 2.06) without; ``--fast`` 1.61-2.04 (1.89) against
    1.53-1.56 (1.54); OpenCV's StereoSGBM script 0.42-0.43 s either way (docs/dense.md, Speed). A loop that
    keeps its arrays (``live``, ``batch``) touches them once either way."""
    if HUGEPAGE_ENV in os.environ:
        return False
    os.environ[HUGEPAGE_ENV] = "0"
    try:
        from numpy._core.multiarray import _set_madvise_hugepage
    except ImportError:                 # a NumPy without the switch: the variable alone, for what starts later
        return False
    _set_madvise_hugepage(False)
    return True
