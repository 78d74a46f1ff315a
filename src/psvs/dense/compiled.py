"""The dense path's Numba kernels, for a first run to say that it compiles them (psvs._compiled)."""
from __future__ import annotations

import hashlib
import importlib
import json
from pathlib import Path

import llvmlite.binding as llvm
import numba

from psvs._cache import cache_dir
from psvs._compiled import notice, quiet, uncompiled
from psvs.io.atomic import write_atomic

#: The file in the user's cache folder that records which kernels a notice was last given for.
NOTICE_FILE = "compile_notice.json"

#: The modules whose kernels psvs disparity, batch disparity, dense-eval, live --dense and serve's dense run (the
#: ray tracer's too: the rectification and depth tables trace the rig).
MODULES = ("psvs.dense.cost", "psvs.dense.sgm", "psvs.dense.band", "psvs.dense.maps", "psvs.dense.median",
           "psvs.dense.guided", "psvs.dense.echo_test", "psvs.dense.trust", "psvs.dense.depth_table",
           "psvs.dense.separate", "psvs.optics.kernels")
#: Kernels no command calls (psvs.dense.sgm.aggregate's: the tests' reference of the aggregation).
NOT_CALLED = ("psvs.dense.sgm._both_passes", "psvs.dense.sgm._add_into")
#: Kernels only some runs call, each compiled in seconds when one does: the pyramid's local winners (the
#: default mode's finest level, not --fast's), the autocorrelation's lag medians (a range starting at small
#: lags), a build's view separation (--views on a build), the band kernels' general copies (bands of other
#: than psvs.dense.band.LANES lanes: parameters of the user's own). A machine that has only run others keeps them
#: uncompiled; they are not what makes a first run take minutes, and they do not make a run say it compiles.
SOME_RUNS = ("psvs.dense.band._local_winners_lanes", "psvs.dense.band._local_row_lanes",
             "psvs.dense.echo_test._lag_medians", "psvs.dense.separate._csr_matvec", "psvs.dense.band._local_winners",
             "psvs.dense.band._local_row_any", "psvs.dense.band._band_winners", "psvs.dense.band._band_map")


def announce_dense(command: str) -> bool:
    """One line on stderr ("compiling N kernels ...") when the kernels every dense run calls will compile on this
    run (those of :data:`SOME_RUNS` aside), unless the last notice (:data:`NOTICE_FILE` in the user's cache
    folder, for this Numba and CPU) already named every one of them: a run refused before the later stages
    (an image without echo) leaves those uncompiled, and would otherwise say it compiles on every call."""
    if quiet():
        return False
    missing = uncompiled(MODULES, NOT_CALLED + SOME_RUNS)
    if not missing:
        return False
    key, folder = _machine(), cache_dir()
    record = None if folder is None else folder / NOTICE_FILE
    try:
        said = json.loads(record.read_text()) if record is not None and record.is_file() else {}
    except (OSError, ValueError):
        said = {}
    if isinstance(said, dict) and said.get("machine") == key and set(missing) <= set(said.get("kernels", ())):
        return False
    notice(command, len(missing))
    if record is not None:
        try:
            record.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(record, json.dumps({"machine": key, "kernels": sorted(missing)}), batch=False)
        except OSError:          # no cache folder to write: the notice comes again next time
            pass
    return True


def _machine() -> str:
    """What compiled code is for and where it is kept: Numba's version, this machine's CPU, and the kernels'
    source files (each one's path and modification time: another install, or psvs updated, compiles again and
    is told so)."""

    files = []
    for name in MODULES:
        path = Path(importlib.import_module(name).__file__)
        files.append(f"{path}:{path.stat().st_mtime_ns}")
    digest = hashlib.sha256("\n".join(files).encode()).hexdigest()[:16]
    return f"numba {numba.__version__} {llvm.get_host_cpu_name()} {digest}"
