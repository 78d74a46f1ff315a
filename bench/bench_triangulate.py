"""Triangulation: 10^6 correspondences, each model (exact <= 1 s, paper models <= 50 ms, one core)."""
import numpy as np

from psvs import default_rig
from psvs.measure.triangulate import triangulate
from psvs.optics.project import project_points

N = 1_000_000


def _matches():
    rig = default_rig()
    rng = np.random.default_rng(0)
    z = rng.uniform(400, 1200, N)
    half_w = (z + 50) * 0.2832 - 50
    half_h = (z + 50) * 0.2124
    pts = np.column_stack([rng.uniform(-1, 1, N) * half_w, rng.uniform(-1, 1, N) * half_h, z])
    left, _ = project_points(pts, rig, "left")
    right, _ = project_points(pts, rig, "right")
    return rig, left, right


_cache = {}


def _setup(model):
    def setup():
        if "m" not in _cache:
            _cache["m"] = _matches()
        rig, left, right = _cache["m"]
        return lambda: triangulate(left, right, rig, model=model)
    return setup


def _project_setup():
    rig = default_rig()
    rng = np.random.default_rng(1)
    pts = np.column_stack([rng.uniform(-100, 100, 100_000), rng.uniform(-80, 80, 100_000),
                           rng.uniform(400, 1200, 100_000)])
    return lambda: project_points(pts, rig, "left")


def cases():
    return [
        ("triangulate 1e6, paper eqs. (12)-(14)", _setup("paper"), 0.050),
        ("triangulate 1e6, refraction eqs. (15)-(17)", _setup("refraction"), 0.050),
        ("triangulate 1e6, exact (ray tracing)", _setup("exact"), 1.0),
        ("project 1e5 points into the left view (iterative)", _project_setup, 1.0),
    ]
