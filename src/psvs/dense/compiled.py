"""The dense path's Numba kernels, for a first run to say that it compiles them (psvs._compiled)."""
from __future__ import annotations

from psvs._compiled import announce

#: The modules whose kernels psvs disparity, batch disparity, dense-eval, live --dense and serve's dense run (the
#: ray tracer's too: the rectification and depth tables trace the rig).
MODULES = ("psvs.dense.cost", "psvs.dense.sgm", "psvs.dense.band", "psvs.dense.maps", "psvs.dense.median",
           "psvs.dense.guided", "psvs.dense.echo_test", "psvs.dense.trust", "psvs.dense.depth_table",
           "psvs.dense.separate", "psvs.optics.kernels")
#: Kernels no command calls (psvs.dense.sgm.aggregate's: the tests' reference of the aggregation).
NOT_CALLED = ("psvs.dense.sgm._both_passes", "psvs.dense.sgm._add_into")
#: Kernels only some runs call, each compiled in seconds when one does: the pyramid's local winners (the
#: default mode's finest level, not --fast's), the autocorrelation's lag medians (a range starting at small
#: lags), a build's view separation (--views on a build). A machine that has only run others keeps them
#: uncompiled; they are not what makes a first run take minutes, and they do not make a run say it compiles.
SOME_RUNS = ("psvs.dense.band._local_winners", "psvs.dense.echo_test._lag_medians", "psvs.dense.separate._csr_matvec")


def announce_dense(command: str) -> bool:
    """One line on stderr ("compiling N kernels ...") when the kernels every dense run calls will compile on this
    run (those of :data:`SOME_RUNS` aside)."""
    return announce(command, MODULES, NOT_CALLED + SOME_RUNS)
