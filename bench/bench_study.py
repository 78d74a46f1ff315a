"""Monte-Carlo tolerancing (psvs.study): one sample of the shipped default study (the default rig, mirrors to
+-0.2 deg and +-0.5 mm, 16 card views rendered at 2x2, calibrated from the nominal design, scored), each call
another build (index 0, 1, ...). Its wall time on this host (rendering uses both cores), and its CPU time
(process time: what a study of N samples costs a cluster, N times this)."""
import itertools
import time

from psvs.io.params import load_rig
from psvs.study.sample import run_sample
from psvs.study.tolerances import load_tolerances


def _sample(cpu: bool):
    nominal, tol = load_rig("default"), load_tolerances("default")
    index = itertools.count()

    def run():
        t = time.process_time()
        row = run_sample(nominal, tol, 2026, next(index))
        assert row["ok"] and row["images_used"] == 16, row["reason"]
        if cpu:
            return time.process_time() - t
    return run


def cases():
    return [("one sample of the default study (16 card views, default rig): wall time", lambda: _sample(False),
             float("inf")),
            ("one sample of the default study (16 card views, default rig): CPU time (process)",
             lambda: _sample(True), float("inf"))]
