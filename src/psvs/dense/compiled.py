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


def announce_dense(command: str) -> bool:
    """One line on stderr ("compiling N kernels ...") when the dense kernels will compile on this run."""
    return announce(command, MODULES, NOT_CALLED)
