"""Where the dense method loses a scene whose texture is finer or coarser than its levels see, run on demand
(a few minutes, not in the suite; docs/dense.md, "Known limits"): scenes rendered through the exact optics
of shipped and designed rigs, scored against the renderer's depth over the pixels the right view also sees
(no answer or |Z error| > 2 % of Z counts as wrong), for the whole frame and by depth band (the scene's
objects), with the wrong answers the echo test trusted.

    python bench/texture_scale_check.py [--one-level]

Rigs: the default 640 x 480 rig, mv1440 and mv1440_misaligned (their true rigs: no calibration, so every
wrong pixel is the matcher's), and "camera B" of the trial of 2026-12-07 (1280 x 1024, 5.3 um, f 16 mm,
b 65 mm, split 0.57), sized by ``psvs design --rig-out`` here. Scenes: the built-in ``textured`` (photos of
a panel, a ball and a brick box before a gravel wall, 560-1120 mm: the photos' pixels are finer than a
1.6 MP camera's coarse level sees), the benchmark's photo cards before a gravel wall whose photo is
magnified to 5.2 mm a texel (14 px a texel on camera B: smooth at the finest band), and the same cards
with the wall's photo at 1.6 mm a texel (the widest field here, 800 mm wide at 1120 mm, still covered).
``--one-level`` also runs the default mode without its pyramid (the whole range at full resolution: 8 GB
and 40 s at 1440 x 1080).
"""
from __future__ import annotations

import contextlib
import dataclasses
import io
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT), str(ROOT / "bench")]

from bench_depth import cards_scene  # noqa: E402

from psvs.cli.main import main as psvs_main  # noqa: E402
from psvs.dense.build import dense_on_rig, rig_depth, rig_trust  # noqa: E402
from psvs.dense.params import DEFAULT, FAST  # noqa: E402
from psvs.io.params import load_rig  # noqa: E402
from psvs.simulate.builtin import textured  # noqa: E402
from psvs.simulate.render import render  # noqa: E402
from psvs.simulate.scene import Scene  # noqa: E402
from tests.support.sweep_scenes import left_truth, truth_on_left_grid  # noqa: E402

NEAR_MM, FAR_MM = 400.0, 1200.0
#: mm: the depth bands scored apart (the textured scene's box, ball, panel and wall)
BANDS = ((520, 600), (600, 700), (700, 1000), (1100, 2000))
CAMERA_B = """[camera]
focal_length_mm = 16.0
pixel_pitch_mm = [0.0053, 0.0053]
image_size_px = [1280, 1024]
principal_point_px = [639.5, 511.5]
distortion = [-0.12, 0.05, 0.0, 0.0, 0.0]
relative_illumination = [-1.0, 0.0]

[mirrors]
baseline_mm = 65.0
m1_axis_distance_mm = 20.0
m2_axis_distance_mm = 40.0
angle_deg = 45.0
plate_thickness_mm = 2.0
refractive_index = 1.5168
split_ratio = 0.57
"""


def camera_b(folder: Path):
    """Camera B's rig with its mirrors sized by ``psvs design --rig-out``."""
    given, sized = folder / "camera_b_in.toml", folder / "camera_b.toml"
    given.write_text(CAMERA_B)
    with contextlib.redirect_stdout(io.StringIO()):          # its mirror table: not this check's output
        code = psvs_main(["design", "--rig", str(given), "--rig-out", str(sized)])
    if code != 0:
        raise SystemExit("psvs design refused camera B")
    return load_rig(sized)


def cards(wall_texel_mm: float) -> Scene:
    """The benchmark's three photo cards (:func:`bench_depth.cards_scene`) before a gravel wall at 1120 mm whose
    photo (512 px) has texels of ``wall_texel_mm``."""
    return cards_scene(NEAR_MM, FAR_MM, (512 * wall_texel_mm, 512 * wall_texel_mm * 1.7 / 2.2))


def score(rig, scene: Scene, params) -> str:
    """One line: the share of twin-visible pixels wrong, the trusted wrong ones, and the share wrong in each
    depth band."""
    frame = render(scene, rig, supersample=1, seed=1).image
    image = np.clip(np.rint(frame), 0, 255).astype(np.uint8)
    dense = dense_on_rig(image, rig, NEAR_MM, FAR_MM, params=params)
    trusted = rig_trust(dense).trusted_left
    z = rig_depth(dense, rig)
    left = left_truth(scene, rig)
    tg = truth_on_left_grid(left, dense.rect, z.shape) if dense.rect is not None else left
    seen = np.isfinite(tg)
    wrong = seen & ~(np.abs(z - tg) <= 0.02 * tg)
    bands = []
    for lo, hi in BANDS:
        m = seen & (tg >= lo) & (tg < hi)
        if m.any():
            bands.append(f"{lo}-{hi} mm {100 * wrong[m].mean():5.1f} %")
    return (f"{100 * wrong.sum() / seen.sum():5.1f} % wrong, {int((wrong & trusted).sum()):6d} px of them trusted;  "
            + ";  ".join(bands))


def main(argv: list[str]) -> None:
    modes = {"default": DEFAULT, "fast": FAST}
    if "--one-level" in argv:
        modes["one level"] = dataclasses.replace(DEFAULT, pyramid=False, prune=False)
    with tempfile.TemporaryDirectory() as tmp:
        rigs = {name: load_rig(name) for name in ("default", "mv1440", "mv1440_misaligned")}
        rigs["camera B"] = camera_b(Path(tmp))
    scenes = {"textured": textured(), "cards, wall 5.2 mm/texel": cards(5.16),
              "cards, wall 1.6 mm/texel": cards(1.6)}
    for rig_name, rig in rigs.items():
        for scene_name, scene in scenes.items():
            for mode, params in modes.items():
                print(f"{rig_name:18s} {scene_name:26s} {mode:9s} {score(rig, scene, params)}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
