import struct

import numpy as np
import pytest

from psvs import default_rig
from psvs.dense import disparity_cloud, write_cloud_ply
from psvs.optics.project import project_points


def on_sensor(block: np.ndarray, d: float) -> np.ndarray:
    """A map (H, d + w) holding ``block`` (H, w) at columns d.., NaN left of it: its pixels' twins u - d
    lie on the sensor (a twin left of u = -0.5 was seen by no pixel, and gives no point)."""
    out = np.full((block.shape[0], int(d) + block.shape[1]), np.nan)
    out[:, int(d):] = block
    return out


def test_paper_model_depth_is_eq_12(rig):
    """A constant disparity of d px is Z = b f / (d pitch) - b/2 (eq. 12) at every pixel whose twin u - d
    is on the sensor; none where it is not."""
    r = rig.replace(plate_thickness_mm=0.0)
    d = np.full((6, 128), 120.0)
    cloud = disparity_cloud(d, r, model="paper")
    b, f, p = r.mirrors.baseline_mm, r.camera.focal_length_mm, r.camera.pixel_pitch_mm[0]
    assert cloud.points_mm.shape == (48, 3)
    np.testing.assert_allclose(cloud.depth_mm[:, 120:], b * f / (120.0 * p) - b / 2, rtol=1e-12)
    assert np.isnan(cloud.depth_mm[:, :120]).all()       # twins off the sensor (u - d < -0.5)


def test_exact_model_recovers_planted_points(rig):
    """Points on a plane are projected into both views by the exact optics; their left pixels with the
    disparity u_l - u_r come back as the same points, plate and all."""
    rng = np.random.default_rng(4)
    pts = np.column_stack([rng.uniform(-150, 150, 40), rng.uniform(-100, 100, 40), rng.uniform(600, 900, 40)])
    uv_l, ok_l = project_points(pts, rig, "left")
    uv_r, ok_r = project_points(pts, rig, "right")
    ok = ok_l & ok_r
    # put each point's disparity on the nearest left pixel and move the point to that pixel's ray
    d = np.full((480, 640), np.nan)
    u, v = np.rint(uv_l[ok]).astype(int).T
    d[v, u] = (uv_l[ok, 0] - uv_r[ok, 0])
    cloud = disparity_cloud(d, rig, model="exact")
    assert len(cloud.points_mm) == ok.sum()
    # depth error from rounding u_l to the pixel centre: below 0.1 % of Z
    z_true = {(a, b): z for a, b, z in zip(u, v, pts[ok, 2], strict=True)}
    for (pu, pv), z in zip(cloud.pixels.astype(int), cloud.points_mm[:, 2], strict=True):
        assert z == pytest.approx(z_true[(pu, pv)], rel=1e-3)


def test_ply_is_binary_and_complete(tmp_path, rig):
    block = np.full((4, 5), 100.0)
    block[0, 0] = np.nan
    d = on_sensor(block, 100)
    cloud = disparity_cloud(d, rig)
    path = tmp_path / "c.ply"
    write_cloud_ply(path, cloud, grey=np.nan_to_num(on_sensor(np.arange(20).reshape(4, 5), 100)).astype(np.uint8))
    raw = path.read_bytes()
    head, body = raw.split(b"end_header\n", 1)
    assert b"format binary_little_endian 1.0" in head and b"element vertex 19" in head
    assert len(body) == 19 * 13
    x, y, z, g = struct.unpack("<fffB", body[:13])
    assert (x, y, z) == pytest.approx(tuple(cloud.points_mm[0]), rel=1e-6) and g == 1


def test_mask_and_bad_shape(rig):
    d = on_sensor(np.full((4, 5), 100.0), 100)
    assert len(disparity_cloud(d, rig, mask=on_sensor(np.eye(4, 5), 100) == 1).points_mm) == 4
    with pytest.raises(ValueError, match=r"\(H, W\)"):
        disparity_cloud(np.zeros(5), default_rig())
