"""Calibration, 2 cores: calibrating a build from 20 hand-held card views (detection of both views' grids in
every image + the bundle adjustment over the exact optics), from PNG files on disk, <= 30 s."""
import tempfile
from pathlib import Path

from psvs.calibrate.folder import calibrate_folder
from psvs.calibrate.synthetic import random_poses, render_grid_shots
from psvs.calibrate.target_file import dumps_target
from psvs.io.images import write_png
from psvs.io.params import load_rig
from psvs.simulate.textures import CircleGrid

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


def cases():
    return [("calibrate a build from 20 card views (detect + bundle adjustment)", _calibrate_20, 30.0)]
