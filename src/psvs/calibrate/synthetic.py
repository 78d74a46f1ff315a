"""Simulated calibration data: a hand-held circle-grid card shown to a rig at random poses.

Poses follow what docs/calibration.md asks a user to do (and what the independent check renders): the card 450-1000 mm
away, tilted up to +-25 deg about both in-plane axes and turned a little about the optical axis, placed so
that every disc of both views lies inside the image with a margin. Rendering goes through the rig's exact
optics (:func:`psvs.simulate.render.render`), so a misaligned build gives the images that build would.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from psvs.optics.project import in_image, project_points
from psvs.optics.rig import Rig
from psvs.simulate.scene import Pose, Scene, SceneObject
from psvs.simulate.textures import AsymmetricCircleGrid, CharucoBoard, CircleGrid, Uniform
from psvs.targets.discs import MAX_DIAMETER_PX, MIN_AREA_PX


@dataclass(frozen=True, eq=False)
class GridShot:
    """One simulated view: the 8-bit complex image, the card's pose (target -> frame C, 4x4 mm) and its
    disc centres in frame C (n, 3) mm."""

    image: np.ndarray
    target2cam: np.ndarray
    centres_mm: np.ndarray


def card_size_mm(grid) -> tuple[float, float]:
    """A card one spacing wider than a circle grid on every side (an asymmetric grid's: one spacing beyond
    its outer discs' rims), or a ChArUco board with half a square of white around it, mm (width, height)."""
    if isinstance(grid, CharucoBoard):
        return (grid.squares_x + 1) * grid.square_mm, (grid.squares_y + 1) * grid.square_mm
    if isinstance(grid, AsymmetricCircleGrid):
        span = np.ptp(grid.centres_mm(), axis=0) + grid.diameter_mm + 2 * grid.spacing_mm
        return float(span[0]), float(span[1])
    return (grid.cols + 1) * grid.spacing_mm, (grid.rows + 1) * grid.spacing_mm


#: What a card refused with its copy apart is told, where it would fit interleaved.
INTERLEAVE_HINT = ("a card wider than its disparity interleaves with its copy, as a hand-held one does: psvs "
                   "card-views --interleave")


def check_card_fits(rig: Rig, grid: CircleGrid, n: int, z_range_mm=(450.0, 1000.0), tilt_deg: float = 25.0,
                    margin_px: float = 12.0, apart: bool = True) -> None:
    """ValueError, before any pose is tried, when no pose of :func:`random_poses` could show the grid: too
    wide or too high for the views at the nearest of the ``n`` depth strata (both copies of the grid side by
    side in the image, ``margin_px`` inside it, and apart by two disc diameters; the tilt foreshortening
    it by at most cos ``tilt_deg``; with ``apart`` False the copies may interleave, so only both side by
    side must fit), or discs outside what the detector finds (psvs.targets.pattern:
    :data:`MIN_AREA_PX` at the farthest poses, :data:`MAX_DIAMETER_PX` at the nearest). Each view is the
    rig's pinhole at its virtual centre; the test is lenient, so a grid it passes may still find no pose."""
    cam, b, zv = rig.camera, rig.mirrors.baseline_mm, rig.virtual_z_mm
    (w, h), (px, py), f = cam.image_size_px, cam.pixel_pitch_mm, cam.focal_length_mm
    z0, z1 = z_range_mm
    near, far = z0 + (z1 - z0) / n, z1 - (z1 - z0) / n     # the nearest stratum's far end, the farthest's near end
    d, cos_t = grid.diameter_mm, math.cos(math.radians(tilt_deg))
    size = ((grid.cols - 1) * grid.spacing_mm + d, (grid.rows - 1) * grid.spacing_mm + d)
    fits = (w - 1 - 2 * margin_px) * px * (near - zv) / f - b - d
    most = ((min(b - 2 * d, fits) if apart else fits) / cos_t,
            ((h - 1 - 2 * margin_px) * py * (near - zv) / f - d) / cos_t)
    if size[0] > most[0] or size[1] > most[1]:
        raise ValueError(f"the grid of discs is {size[0]:g} x {size[1]:g} mm ({grid.cols} x {grid.rows} discs "
                         f"{grid.spacing_mm:g} mm apart, {d:g} mm across); this rig's views hold at most "
                         f"{max(most[0], 0):.0f} x {max(most[1], 0):.0f} mm of it at {z0:g}-{near:.0f} mm, the "
                         f"nearest of the {n} poses (both copies of the grid side by side, "
                         + ("interleaved)" if not apart else f"apart: {INTERLEAVE_HINT})"
                            if size[0] <= fits / cos_t and size[1] <= most[1] else "apart)"))
    smallest, largest = 2 * math.sqrt(MIN_AREA_PX / math.pi), MAX_DIAMETER_PX
    at_far, at_near = d * f / (px * (far - zv)), d * f / (px * (near - zv))
    if at_far < smallest or at_near > largest:
        where = (f"{at_far:.2g} px across at {far:.0f}-{z1:g} mm, the farthest poses" if at_far < smallest else
                 f"{at_near:.3g} px across at {z0:g}-{near:.0f} mm, the nearest poses")
        raise ValueError(f"the discs ({d:g} mm) are {where}, through this rig; the detector finds discs "
                         f"{smallest:.1f}-{largest} px across: none of the {grid.cols * grid.rows} would be found")


def random_poses(rig: Rig, grid, n: int, seed: int = 0, z_range_mm=(450.0, 1000.0),
                 tilt_deg: float = 25.0, margin_px: float = 12.0, apart: bool = True) -> list[Pose]:
    """``n`` card poses spread over the depth range (stratified), tilted up to ``tilt_deg`` about X and Y,
    turned up to 8 deg about Z, with every target point seen in both views ``margin_px`` inside the image.
    With ``apart`` the two copies of the grid are apart (no disc of one view within two diameters of the
    other view's grid); without, they may interleave as a hand-held card's do, only no two discs of the
    two views closer than a radius (discs on top of each other are one blob). A grid no pose could show is
    refused first (:func:`check_card_fits`); ``grid`` may be any target (psvs.targets.detect.Target)."""
    from psvs.targets.target_points import target_points_mm
    if isinstance(grid, CircleGrid):
        check_card_fits(rig, grid, n, z_range_mm, tilt_deg, margin_px, apart)
    max_tries = 2000
    rng = np.random.default_rng(seed)
    local = target_points_mm(grid)
    local = np.column_stack([local, np.zeros(len(local))])
    r_disc = getattr(grid, "diameter_mm", 0.0) / 2
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
            if apart:
                ok &= bool(seen[0][:, 0].min() - seen[1][:, 0].max() > 4 * r_px)
            else:
                ok &= bool(np.linalg.norm(seen[0][:, None] - seen[1][None], axis=2).min() > max(r_px, 3.0))
            if ok:
                out.append(pose)
                break
        else:
            raise ValueError(f"no pose at {edges[k]:.0f}-{edges[k + 1]:.0f} mm shows the whole grid in both views"
                             + (f" with its two copies apart: {INTERLEAVE_HINT}" if apart else ""))
    return out


def render_grid_shots(rig: Rig, grid: CircleGrid, poses: list[Pose], seed: int = 0,
                      supersample: int = 2, sensor=None) -> list[GridShot]:
    """Render the card (any target: its printed image) at each pose through ``rig`` (realistic sensor: blur
    and noise, seeded; ``sensor`` a :class:`psvs.simulate.sensor.Sensor`, the renderer's default when None),
    adaptively (a card on a plain backdrop: its discs and squares are wider than 3 px on any rig that can
    detect them, :mod:`psvs.simulate.adaptive`)."""
    from psvs.simulate.builtin import regulated_light
    from psvs.simulate.render import render
    from psvs.targets.target_points import target_points_mm
    size = card_size_mm(grid)
    local = target_points_mm(grid)
    local = np.column_stack([local, np.zeros(len(local))])
    shots = []
    for k, pose in enumerate(poses):
        z = float(pose.position_mm[2])
        card = SceneObject("rectangle", pose, grid, size_mm=size)
        scene = Scene((card,), regulated_light(z), z + 400.0, Uniform(0.08))
        extra = {} if sensor is None else {"sensor": sensor}
        img = render(scene, rig, seed=seed + k, supersample=supersample, adaptive=True, **extra).image
        shots.append(GridShot(img, pose.matrix, pose.to_world(local)))
    return shots
