"""Calibration, 2 cores: calibrating a build from 20 hand-held card views (detection of both views' grids in
every image + the bundle adjustment over the exact optics), from PNG files on disk, <= 30 s."""
import tempfile
from pathlib import Path

from psvs.calibrate.folder import calibrate_folder
from psvs.calibrate.synthetic import random_poses, render_grid_shots
from psvs.io.images import write_png
from psvs.io.params import load_rig
from psvs.simulate.textures import CircleGrid
from psvs.targets.target_file import dumps_target

RIGS = Path(__file__).resolve().parents[1] / "examples" / "rigs"


def _calibrate_20():
    card = CircleGrid(4, 6, 14.0, 7.0)
    true = load_rig(RIGS / "misaligned.toml")
    folder = Path(tempfile.mkdtemp(prefix="psvs-bench-cal-"))
    for k, shot in enumerate(render_grid_shots(true, card, random_poses(true, card, 20, seed=11), seed=7)):
        write_png(folder / f"card_{k:02d}.png", shot.image)
    (folder / "target.toml").write_text(dumps_target(card))
    nominal = load_rig(RIGS / "clear.toml").with_extents({k: None for k in ("m1", "m2", "m3", "m4")})

    def run():
        res = calibrate_folder(folder, nominal)
        assert len(res.used) == 20 and res.bundle.rms_px < 0.05
    return run


def _calibrate_mv1440():
    """20 views of a 5x7 card wider than its disparity (every view interleaved) through mv1440_misaligned,
    calibrated from mv1440 (the acceptance of tests/calibrate/test_card_mv1440.py)."""
    from psvs.rigs import shipped_rig_path
    card = CircleGrid(5, 7, 16.0, 7.0)
    true = load_rig(shipped_rig_path("mv1440_misaligned"))
    folder = Path(tempfile.mkdtemp(prefix="psvs-bench-cal1440-"))
    poses = random_poses(true, card, 20, seed=1, z_range_mm=(400.0, 900.0), apart=False)
    for k, shot in enumerate(render_grid_shots(true, card, poses, seed=1)):
        write_png(folder / f"card_{k:02d}.png", shot.image)
    (folder / "target.toml").write_text(dumps_target(card))
    nominal = load_rig(shipped_rig_path("mv1440"))

    def run():
        res = calibrate_folder(folder, nominal)
        assert len(res.used) >= 18 and res.bundle.rms_px < 0.05
    return run


def cases():
    return [("calibrate a build from 20 card views (detect + bundle adjustment)", _calibrate_20, 30.0),
            ("calibrate mv1440 from 20 interleaving card views, 1440x1080 (detect + bundle adjustment)",
             _calibrate_mv1440, float("inf"))]
