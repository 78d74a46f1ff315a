"""Simulated calibration data: a hand-held circle-grid card shown to a rig at random poses.

Poses follow what docs/calibration.md asks a user to do (and what the independent check renders): the card 450-1000 mm
away, tilted up to +-25 deg about both in-plane axes and turned a little about the optical axis, placed so
that every disc of both views lies inside the image with a margin. Rendering goes through the rig's exact
optics (:func:`psvs.simulate.render.render`), so a misaligned build gives the images that build would.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from psvs.optics.project import in_image, project_points
from psvs.optics.rig import Rig
from psvs.simulate.scene import Pose, Scene, SceneObject
from psvs.simulate.textures import CircleGrid, Uniform


@dataclass(frozen=True, eq=False)
class GridShot:
    """One simulated view: the 8-bit complex image, the card's pose (target -> frame C, 4x4 mm) and its
    disc centres in frame C (n, 3) mm."""

    image: np.ndarray
    target2cam: np.ndarray
    centres_mm: np.ndarray


def card_size_mm(grid: CircleGrid) -> tuple[float, float]:
    """A card one spacing wider than the grid on every side, mm (width, height)."""
    return (grid.cols + 1) * grid.spacing_mm, (grid.rows + 1) * grid.spacing_mm


def random_poses(rig: Rig, grid: CircleGrid, n: int, seed: int = 0, z_range_mm=(450.0, 1000.0),
                 tilt_deg: float = 25.0, margin_px: float = 12.0, max_tries: int = 2000) -> list[Pose]:
    """``n`` card poses spread over the depth range (stratified), tilted up to ``tilt_deg`` about X and Y,
    turned up to 8 deg about Z, with every disc seen in both views ``margin_px`` inside the image and the
    two copies of the grid apart (no disc of one view within two diameters of the other view's grid)."""
    rng = np.random.default_rng(seed)
    local = np.column_stack([grid.centres_mm(), np.zeros(grid.rows * grid.cols)])
    r_disc = grid.diameter_mm / 2
    w, h = rig.camera.image_size_px
    out = []
    edges = np.linspace(*z_range_mm, n + 1)
    for k in range(n):
        for _ in range(max_tries):
            z = rng.uniform(edges[k], edges[k + 1])
            rx, ry = rng.uniform(-tilt_deg, tilt_deg, 2)
            rz = rng.uniform(-8.0, 8.0)
            x, y = rng.uniform(-0.16, 0.16) * z, rng.uniform(-0.16, 0.16) * z
            pose = Pose.from_euler_deg([x, y, z], [rx, ry, rz])
            pts = pose.to_world(local)
            ok = True
            r_px = r_disc * rig.camera.focal_length_mm / rig.camera.pixel_pitch_mm[0] / z
            seen = []
            for view in ("left", "right"):
                uv, valid = project_points(pts, rig, view)
                m = margin_px + r_px
                inside = (uv[:, 0] > m) & (uv[:, 0] < w - 1 - m) & (uv[:, 1] > m) & (uv[:, 1] < h - 1 - m)
                ok &= bool(valid.all() and inside.all() and in_image(uv, rig).all())
                seen.append(uv)
            # the two copies of the grid must not interleave: every right-view disc left of every left-view
            # disc by more than two disc diameters (the cards themselves may touch or overlap)
            ok &= bool(seen[0][:, 0].min() - seen[1][:, 0].max() > 4 * r_px)
            if ok:
                out.append(pose)
                break
        else:
            raise ValueError(f"no pose at {edges[k]:.0f}-{edges[k + 1]:.0f} mm shows the whole grid in both views")
    return out


def render_grid_shots(rig: Rig, grid: CircleGrid, poses: list[Pose], seed: int = 0,
                      supersample: int = 2) -> list[GridShot]:
    """Render the card at each pose through ``rig`` (realistic sensor: blur and noise, seeded)."""
    from psvs.simulate.builtin import regulated_light
    from psvs.simulate.render import render
    size = card_size_mm(grid)
    local = np.column_stack([grid.centres_mm(), np.zeros(grid.rows * grid.cols)])
    shots = []
    for k, pose in enumerate(poses):
        z = float(pose.position_mm[2])
        card = SceneObject("rectangle", pose, grid, size_mm=size)
        scene = Scene((card,), regulated_light(z), z + 400.0, Uniform(0.08))
        img = render(scene, rig, seed=seed + k, supersample=supersample).image
        shots.append(GridShot(img, pose.matrix, pose.to_world(local)))
    return shots
