"""A depth map on a build at camera formats of today (issue 40): ``psvs disparity --depth`` beside OpenCV's
StereoSGBM 3-way on a same-size separate pair with the same disparity count (rounded up to 16), measured in
the same run, on two builds: mv1440_misaligned (1440x1080, 3.45 um, 8 mm, 400-1200 mm) and a 1920x1200
build (5.86 um, 16 mm lens, b 120 mm, 55/45 split, 3 mm plate, 600-1100 mm; bench/rigs/build_1920x1200.toml,
calibrated by psvs from 20 simulated hand-held card views).

- The library call: what the command computes, in one warm process (the rig's tables in memory):
  ``dense_on_rig`` + ``rig_trust`` + ``rig_depth`` (a depth map, no point list: what
  ``--depth`` writes); against ``sgbm_reference`` on the two views rendered
  alone. Targets as ratios: default <= 2x, --fast <= 0.7x.
- The whole call: a fresh process each time, warm (its Numba kernels compiled and the rig's tables in the
  cache folder, as on every call after a user's first): ``psvs disparity FRAME --rig BUILD -o D.npy --depth
  Z.npy`` against ``python bench/sgbm_depth.py`` (reads the pair, StereoSGBM 3-way, reprojectImageTo3D,
  writes Z). Targets as ratios: default <= 3x, --fast <= 1x. The processes' peak resident memory (GNU
  time's maximum resident set size of each child) is written beside (limit 1 GiB).

The frames (photo cards at three depths before a photo wall, through each build, and the views alone) are
rendered once into out/bench/.
"""
from __future__ import annotations

import math
import os
import subprocess
import sys
import time
from pathlib import Path

import cv2

from psvs.dense.evaluate import sgbm_reference
from psvs.dense.params import DEFAULT, FAST, DenseParams
from psvs.dense.workspace import Workspace
from psvs.imaging.grey import to_grey8

HERE = Path(__file__).resolve().parent
OUT = HERE.parent / "out" / "bench"
BUILDS = {"1440x1080": ("mv1440_misaligned", 400.0, 1200.0),
          "1920x1200": (str(HERE / "rigs" / "build_1920x1200.toml"), 600.0, 1100.0)}
#: peak resident memory of the whole calls, MiB, by case name (bench/run.py writes them beside the times)
MEMORY: dict[str, float] = {}
MEMORY_LIMIT_MIB = 1024.0
_frames: dict = {}


def cards_scene(near: float, far: float, wall_mm: tuple[float, float] | None = None):
    """The benchmark's scene for a working range near..far mm: three photo cards at 20, 45 and 70 % of it,
    turned a little, before a gravel wall at 90 %; the wall's photo (512 px) stretched over ``wall_mm`` (width,
    height; default 2.2 x 1.7 times ``far``, which covers every shipped rig's field)."""
    from psvs.simulate.builtin import photo_texture, pose_at, regulated_light
    from psvs.simulate.scene import Scene, SceneObject
    span = far - near
    cards = tuple(SceneObject("rectangle", pose_at(x, y, near + f * span, 0, ry, rz), photo_texture(photo, size),
                              size_mm=size)
                  for x, y, f, ry, rz, photo, size in ((-70, -20, 0.2, 10, 5, "astronaut", (120, 90)),
                                                       (60, 40, 0.45, -15, -4, "coffee", (150, 110)),
                                                       (-20, 60, 0.7, 5, 2, "chelsea", (160, 120))))
    wall = photo_texture("gravel", wall_mm or (2.2 * far, 1.7 * far))
    return Scene(cards, regulated_light(0.5 * (near + far)), near + 0.9 * span, wall, "bench")


def _frame(fmt: str) -> dict:
    """The build's complex image and views alone (PNG files in out/bench/), its rig and the dense search's
    disparity count."""
    if fmt in _frames:
        return _frames[fmt]
    from psvs.io.images import read_grey, write_png
    from psvs.io.params import load_rig
    from psvs.optics.search_range import disparity_range, rectification_for
    from psvs.simulate.render import render
    name, near, far = BUILDS[fmt]
    rig = load_rig(name)
    paths = {k: OUT / f"depth_{fmt}_{k}.png" for k in ("complex", "left", "right")}
    if not all(p.exists() for p in paths.values()):
        OUT.mkdir(parents=True, exist_ok=True)
        rr = render(cards_scene(near, far), rig, supersample=1, seed=1)
        # the views alone are radiance (0..1): as grey levels, a camera's 8 bits at full well
        for key, img in (("complex", rr.image), ("left", 255.0 * rr.left), ("right", 255.0 * rr.right)):
            write_png(paths[key], to_grey8(img))
    rect = rectification_for(rig, near, far)
    lo, hi = disparity_range(rig, near, far, rect, width_px=rect.size_px[0])
    f_px = rig.camera.focal_length_mm / rig.camera.pixel_pitch_mm[0]
    _frames[fmt] = dict(rig=rig, rig_name=name, near=near, far=far, paths=paths,
                        image=read_grey(paths["complex"]), left=read_grey(paths["left"]),
                        right=read_grey(paths["right"]), count=int(math.ceil(hi - lo)), f_px=f_px,
                        baseline=rig.mirrors.baseline_mm)
    return _frames[fmt]


def _library(fmt: str, params: DenseParams):
    def setup():
        from psvs.dense.build import dense_on_rig, rig_depth, rig_trust
        s = _frame(fmt)
        ws = Workspace()

        def run():
            dense = dense_on_rig(s["image"], s["rig"], s["near"], s["far"], params=params, workspace=ws)
            rig_trust(dense)
            rig_depth(dense, s["rig"])
        run()                               # the rig's tables into memory, the kernels compiled
        return run
    return setup


def _sgbm_library(fmt: str):
    def setup():
        s = _frame(fmt)

        def run():
            previous = cv2.getNumThreads()
            cv2.setNumThreads(os.cpu_count() or 1)
            try:
                sgbm_reference(s["left"], s["right"], s["count"])
            finally:
                cv2.setNumThreads(previous)
        return run
    return setup


#: GNU time, which reports its child's peak resident memory (the kernel's maxrss of a process forked from
#: this large one would count this one's pages: Linux carries maxrss across exec).
GNU_TIME = "/usr/bin/time"


#: Variables a user's shell does not set: the bench's one-thread BLAS setting, and the bytecode switch of this
#: machine's environment (PYTHONDONTWRITEBYTECODE=1: without it Python writes each module's compiled bytecode
#: beside its source on a first import, as on a user's machine, and reads it on every import after).
_NOT_A_USERS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "PYTHONDONTWRITEBYTECODE")


def _child(args: list[str], name: str) -> float:
    """Run ``args`` in a fresh process, in the environment of a user's shell (:data:`_NOT_A_USERS` removed);
    its wall time in s, its peak resident memory into MEMORY[name] (the largest over the calls; through GNU
    time, none without it). The first call of a case is the warm-up: a user's first call compiles psvs's
    modules to bytecode and its Numba kernels, and caches the rig's tables; the calls timed after it find
    them (until 2026-12-07 this machine's PYTHONDONTWRITEBYTECODE=1 reached the child, and every timed call
    compiled the 80 modules of ``psvs disparity`` from their sources again: 0.13-0.3 s of its 1.8)."""
    env = {k: v for k, v in os.environ.items() if k not in _NOT_A_USERS}
    report = OUT / "maxrss_kib.txt"
    timed = [GNU_TIME, "-f", "%M", "-o", str(report), *args] if os.access(GNU_TIME, os.X_OK) else args
    t0 = time.perf_counter()
    proc = subprocess.run(timed, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=OUT)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(args)} exited {proc.returncode}: {proc.stderr.decode(errors='replace')}")
    if timed is not args:
        MEMORY[name] = max(MEMORY.get(name, 0.0), float(report.read_text().split()[-1]) / 1024.0)
    return wall


def _psvs_whole(fmt: str, fast: bool, name: str):
    def setup():
        s = _frame(fmt)
        psvs = str(Path(sys.executable).with_name("psvs"))
        args = [psvs, "disparity", str(s["paths"]["complex"]), "--rig", s["rig_name"], "--near-mm", f"{s['near']:g}",
                "--far-mm", f"{s['far']:g}", "-o", f"d_{fmt}.npy", "--depth", f"z_{fmt}.npy"] + (["--fast"] * fast)
        _child(args, name)                  # warm: compiled, the rig's tables in the cache folder
        return lambda: _child(args, name)
    return setup


def _sgbm_whole(fmt: str, name: str):
    def setup():
        s = _frame(fmt)
        args = [sys.executable, str(HERE / "sgbm_depth.py"), str(s["paths"]["left"]), str(s["paths"]["right"]),
                str(s["count"]), f"{s['f_px']!r}", f"{s['baseline']!r}", f"sgbm_z_{fmt}.npy"]
        _child(args, name)
        return lambda: _child(args, name)
    return setup


def _numba_floor():
    def setup():
        args = [sys.executable, str(HERE / "numba_floor.py")]
        _child(args, NUMBA_FLOOR)           # warm: its kernel compiled into Numba's cache
        return lambda: _child(args, NUMBA_FLOOR)
    return setup


NUMBA_FLOOR = ("Numba's own start-up: a fresh process importing NumPy and Numba and running one cached one-line "
               "kernel (bench/numba_floor.py)")


def _names(fmt: str) -> dict:
    return {"lib_default": f"{fmt} build: dense (default) + trust + depth, library call, 2 cores",
            "lib_fast": f"{fmt} build: dense --fast + trust + depth, library call, 2 cores",
            "lib_sgbm": f"{fmt}: OpenCV StereoSGBM 3-way on a separate pair, the same disparity count, all cores",
            "whole_default": f"{fmt} build: psvs disparity --depth, whole call (fresh process, warm)",
            "whole_fast": f"{fmt} build: psvs disparity --depth --fast, whole call (fresh process, warm)",
            "whole_sgbm": f"{fmt}: bench/sgbm_depth.py (read, StereoSGBM 3-way, reprojectImageTo3D, write), "
                          "whole call"}


RATIOS = []
for _fmt in BUILDS:
    _n = _names(_fmt)
    RATIOS += [(f"{_fmt} library call, default / StereoSGBM 3-way (target 2)", _n["lib_default"], _n["lib_sgbm"]),
               (f"{_fmt} library call, --fast / StereoSGBM 3-way (target 0.7)", _n["lib_fast"], _n["lib_sgbm"]),
               (f"{_fmt} whole call, default / StereoSGBM 3-way script (target 3)", _n["whole_default"],
                _n["whole_sgbm"]),
               (f"{_fmt} whole call, --fast / StereoSGBM 3-way script (target 1)", _n["whole_fast"],
                _n["whole_sgbm"]),
               (f"Numba's own start-up / the {_fmt} StereoSGBM 3-way script (a floor under psvs's whole call)",
                NUMBA_FLOOR, _n["whole_sgbm"])]


def cases():
    out = [(NUMBA_FLOOR, _numba_floor(), float("inf"))]
    for fmt in BUILDS:
        n = _names(fmt)
        out += [(n["lib_sgbm"], _sgbm_library(fmt), float("inf")),
                (n["lib_default"], _library(fmt, DEFAULT), float("inf")),
                (n["lib_fast"], _library(fmt, FAST), float("inf")),
                (n["whole_sgbm"], _sgbm_whole(fmt, n["whole_sgbm"]), float("inf")),
                (n["whole_default"], _psvs_whole(fmt, False, n["whole_default"]), float("inf")),
                (n["whole_fast"], _psvs_whole(fmt, True, n["whole_fast"]), float("inf"))]
    return out
