"""Rendering: a 640x480 complex image with 2x2 supersampling and <= 20 primitives: <= 1 s on 2 cores; the
same on the machine-vision camera (mv1440: 1440x1080, 5.06 times the pixels, its finite mirrors' occlusion
test and the lens's fall-off): <= 5 s.

The rig's ray bundle (every sub-pixel's chief ray through the mirrors and the plate) depends only on the
rig and is computed once per rig (``view_rays`` cache); 'first frame' includes it, 'per frame' does not.
Uses both cores (Embree and NumPy chunks on a thread pool): this group is not single-threaded.
"""
from pathlib import Path

from psvs import default_rig
from psvs.io.params import load_rig
from psvs.io.scene_file import load_scene
from psvs.simulate.builtin import builtin_scene
from psvs.simulate.radiance import view_rays
from psvs.simulate.render import render

SCENES = Path(__file__).resolve().parents[1] / "examples" / "scenes"


def _frame(scene, rig_name: str = "default"):
    def setup():
        rig = load_rig(rig_name)
        render(scene, rig)  # warm the ray-bundle cache
        return lambda: render(scene, rig)
    return setup


def _first_frame():
    scene = builtin_scene("fig6")

    def run():
        view_rays.cache_clear()
        render(scene, default_rig())
    return run


RATIOS = [("mv1440 1440x1080 / 640x480, fig6 per frame (same run)",
           "render fig6 through mv1440, 1440x1080, 2x2, per frame",
           "render fig6 (15 primitives), 640x480, 2x2, per frame")]


def cases():
    return [
        ("render fig6 (15 primitives), 640x480, 2x2, per frame", _frame(builtin_scene("fig6")), 1.0),
        ("render desk.toml (7 primitives), 640x480, 2x2, per frame", _frame(load_scene(SCENES / "desk.toml")), 1.0),
        ("render fig6, first frame (incl. tracing the rig's rays)", _first_frame, 3.0),
        ("render fig6 through mv1440, 1440x1080, 2x2, per frame", _frame(builtin_scene("fig6"), "mv1440"), 5.0),
    ]
