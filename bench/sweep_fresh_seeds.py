"""The dense sweep on seeds the suite never runs, on demand (minutes per draw, not in the suite; docs/dense.md,
"Known limits"): each seed's draw (tests/support/rig_draws.py: a camera, a lens, a build, a sensor and a file
format drawn as a user's would be) calibrated from its simulated hand-held card views, then its five scenes
(tests/support/sweep_scenes.py) in both modes, scored as the suite scores them. For a failing textured scene
it says where the wrong pixels lie: by depth (the nearer objects against the wall behind them) and how many of
them the trust test trusted, so that a failure is read, not only counted.

    python bench/sweep_fresh_seeds.py small|mid SEED [SEED ...]
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT)]

from psvs.dense.build import dense_on_rig, rig_cloud, rig_trust  # noqa: E402
from psvs.dense.params import DEFAULT, FAST  # noqa: E402
from tests.support.rig_draws import calibrated_draw  # noqa: E402
from tests.support.sweep_scenes import (  # noqa: E402
    MAX_BAD,
    MID,
    SCENES,
    SMALL,
    TEXTURED,
    shot,
    truth_on_left_grid,
)

SIZES = {"small": SMALL, "mid": MID}


def scene_line(seed: int, sizes, scene: str, mode: str) -> str:
    """One scene in one mode: the bad share against its limit, and for a textured one, where the wrong pixels
    lie (the nearer half of the scene's depths against the rest) and how many wrong ones were trusted."""
    cal = calibrated_draw(seed, sizes)
    s = shot(seed, scene, sizes)
    near, far = cal.draw.near_mm, cal.draw.far_mm
    dense = dense_on_rig(s.image, cal.rig, near, far, params=FAST if mode == "fast" else DEFAULT)
    trusted = rig_trust(dense).trusted_left
    if scene not in TEXTURED:
        verdict = "ok" if not trusted.any() else "ANSWERED"
        return f"seed {seed} {scene} {mode}: {verdict} ({int(trusted.sum())} px trusted)"
    cloud = rig_cloud(dense, cal.rig)
    truth = s.truth_mm if dense.rect is None else truth_on_left_grid(s.truth_mm, dense.rect, cloud.depth_mm.shape)
    valid = np.isfinite(truth)
    bad = valid & ~(np.abs(cloud.depth_mm - truth) <= 0.02 * truth)       # no answer is wrong
    share = bad.sum() / valid.sum()
    front = valid & (truth < near + 0.6 * (far - near))
    verdict = "ok" if share <= MAX_BAD[mode] and trusted.any() else "FAIL"
    return (f"seed {seed} {scene} {mode}: {verdict} {share:.1%} wrong (limit {MAX_BAD[mode]:.0%}); the nearer "
            f"objects {front.sum()} px, {bad[front].sum() / max(front.sum(), 1):.0%} of them wrong; wrong and "
            f"trusted {np.sum(bad & trusted) / valid.sum():.1%}")


def main(argv: list[str]) -> int:
    if len(argv) < 2 or argv[0] not in SIZES:
        print(__doc__)
        return 2
    sizes = SIZES[argv[0]]
    for seed in (int(a) for a in argv[1:]):
        t0 = time.perf_counter()
        try:
            cal = calibrated_draw(seed, sizes)
        except AssertionError as exc:            # the draw's card views do not calibrate at all
            print(f"seed {seed}: not calibrated: {str(exc).splitlines()[0]}")
            continue
        print(f"seed {seed}: {cal.draw.describe().splitlines()[0]}; calibrated to {cal.error_mm:.3f} mm "
              f"({'ok' if cal.ok else 'MISSES 0.1 mm'}, {time.perf_counter() - t0:.0f} s)", flush=True)
        for scene in SCENES:
            for mode in MAX_BAD:
                print(scene_line(seed, sizes, scene, mode), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
