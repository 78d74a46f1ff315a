from pathlib import Path

import numpy as np
import pytest

from psvs.io.scene_file import load_scene
from psvs.simulate.builtin import BUILTINS, builtin_scene, describe, seam_centre_line
from psvs.simulate.render import render
from psvs.simulate.sensor import IDEAL
from psvs.simulate.textures import ImageTexture

SCENES = Path(__file__).resolve().parents[2] / "examples" / "scenes"


def test_example_scene_loads_and_renders(small_rig):
    scene = load_scene(SCENES / "desk.toml")
    kinds = [o.kind for o in scene.objects]
    assert kinds == ["rectangle", "rectangle", "box", "cylinder", "sphere", "mesh"]
    assert isinstance(scene.objects[1].texture, ImageTexture)
    res = render(scene, small_rig, supersample=1, sensor=IDEAL)
    assert res.image.shape == (120, 160) and 20 < res.image.mean() < 120


@pytest.mark.parametrize("path", sorted(SCENES.glob("*.toml")), ids=lambda p: p.name)
def test_every_example_scene_renders(path, small_rig):
    res = render(load_scene(path), small_rig, supersample=1, sensor=IDEAL)
    assert res.image.mean() > 5


def write(tmp_path, text):
    p = tmp_path / "scene.toml"
    p.write_text(text)
    return p


OBJ = '[[objects]]\ntype = "rectangle"\nsize_mm = [10, 10]\nposition_mm = [0, 0, 500]\n'


@pytest.mark.parametrize("text, exc, message", [
    (OBJ.replace("rectangle", "cone"), ValueError, r"objects\[0\]: unknown primitive 'cone'"),
    (OBJ.replace("[10, 10]", "[0, 10]"), ValueError, r"objects\[0\]: rectangle: size_mm must be > 0 mm, got 0"),
    (OBJ.replace("[10, 10]", "[-5, 10]"), ValueError, r"size_mm must be > 0 mm"),
    (OBJ + 'texture = { type = "image", file = "missing.png" }\n', FileNotFoundError, "texture file not found"),
    (OBJ + 'texture = { type = "marble" }\n', ValueError, "unknown texture type 'marble'"),
    (OBJ + 'colour = 3\n', ValueError, r"unknown key objects\[0\]\.colour \(allowed: albedo, "),
    ('[[objects]]\ntype = "mesh"\nfile = "nope.stl"\n', FileNotFoundError, "mesh file not found"),
    ('[[objects]]\ntype = "sphere"\nradius_mm = -2\n', ValueError, "radius_mm must be > 0 mm"),
    (OBJ + '[lighting]\nsun = 1\n', ValueError, r"unknown key lighting\.sun \(allowed: ambient, lamp, "),
    ("[[objects]\n", ValueError, "malformed TOML"),
    ("", ValueError, "a scene needs at least one object or a backdrop"),
    (OBJ + 'texture = { type = "checker", square_mm = -4 }\n', ValueError, "square_mm must be > 0 mm"),
    (OBJ + 'texture = { type = "noise", high = 1.5 }\n', ValueError, r"high must be an albedo in \[0, 1\]"),
    (OBJ + 'texture = { type = "circles", count = 1000000000 }\n', ValueError,
     "count must be at most 1000 circles in a row, got 1000000000"),
    (OBJ * 1001, ValueError, r"1001 objects, at most 1000 \(a shape of many parts is one mesh object"),
    # trial 45: a numpy repr, and no file name (said when the backdrop was built, after the file was read)
    ("[backdrop]\nz_mm = 1e300\n", ValueError, r"backdrop z_mm must be at most 1e\+07 mm, got 1e\+300 \(the ray"),
    (OBJ.replace("[0, 0, 500]", "[0, 0, 2e7]"), ValueError, r"position beyond 1e\+07 mm, got \[0, 0, 2e\+07\]"),
])
def test_bad_scene_files(tmp_path, text, exc, message):
    path = write(tmp_path, text)
    with pytest.raises(exc, match=message) as info:
        load_scene(path)
    assert str(path) in str(info.value)


MESH = '[[objects]]\ntype = "mesh"\nfile = "{file}"\n'


@pytest.mark.parametrize("file, content, message", [
    ("photo.png", None, r"not a mesh trimesh can read \(STL, OBJ, PLY, ...\): .*photo\.png \(file_type 'png' not"),
    ("broken.obj", b"v 1 2\nf 1 2 3\n", r"not a mesh trimesh can read .*broken\.obj \("),
    ("empty.stl", b"", r".*empty\.stl holds no triangles"),
    ("points.ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
     b"property float z\nend_header\n0 0 0\n", r".*points\.ply holds no triangles"),
])
def test_a_mesh_file_that_is_no_mesh(tmp_path, file, content, message):
    """trimesh's own errors (NotImplementedError for a PNG, IndexError inside a broken OBJ) or an empty mesh:
    one line naming the scene file, the object's key and the mesh file."""
    from psvs.io.images import write_png
    if content is None:
        write_png(tmp_path / file, np.full((8, 8), 7, np.uint8))
    else:
        (tmp_path / file).write_bytes(content)
    path = write(tmp_path, MESH.format(file=file))
    with pytest.raises(ValueError, match=rf"^{path}: objects\[0\]\.file: {message}") as info:
        load_scene(path)
    assert "\n" not in str(info.value)


def test_builtins_render(small_rig):
    for name in BUILTINS:
        res = render(builtin_scene(name), small_rig, supersample=1, sensor=IDEAL)
        assert res.image.mean() > 5, name
    assert [d[0] for d in describe()] == list(BUILTINS)


def test_fig5a_views_are_separated_and_fig5b_overlap(small_rig):
    """Fig. 5a: no pixel sees an object in both views; Fig. 5b: the ashtrays' views overlap."""
    def object_masks(scene):
        res = render(scene, small_rig, supersample=1, sensor=IDEAL, truth=True)
        back = scene.backdrop_z_mm
        return (res.truth.depth_left_mm < back - 1), (res.truth.depth_right_mm < back - 1)
    left, right = object_masks(builtin_scene("fig5a"))
    assert left.sum() > 100 and right.sum() > 100 and not (left & right).any()
    left, right = object_masks(builtin_scene("fig5b"))
    assert (left & right).sum() > 100


@pytest.mark.parametrize("diameter, spacing, count", [(10, 20, 5), (10, 8, 7), (3, 20, 1), (25, 10, 4),
                                                    (0.5, 0.7, 1000)])
def test_circles_are_the_union_of_their_discs(diameter, spacing, count):
    """The row of circles (one test a point, against its nearest centre) against the union of every disc, on
    points drawn over the row and beyond its ends, overlapping discs included."""
    from psvs.simulate.textures import Circles
    c = Circles(diameter, spacing, count)
    xy = np.random.default_rng(count).uniform(-1, 1, (50000, 2)) * [spacing * (count + 2) / 2, diameter]
    union = np.zeros(len(xy), bool)
    for cx, cy in c.centres_mm():
        union |= (xy[:, 0] - cx) ** 2 + (xy[:, 1] - cy) ** 2 <= (diameter / 2) ** 2
    assert union.any() and not union.all()
    np.testing.assert_array_equal(c(xy), np.where(union, c.low, c.high))


def test_fig9_pattern_geometry():
    scene = builtin_scene("fig9:distance_mm=800,tilt_y_deg=10")
    sheet = scene.objects[0]
    assert sheet.pose.position_mm[2] == 800.0
    centres = sheet.texture.centres_mm()
    assert np.linalg.norm(centres[-1] - centres[0]) == pytest.approx(80.0)   # Table I's "a"
    assert sheet.texture.diameter_mm == 10.0


def test_builtin_errors():
    with pytest.raises(ValueError, match="unknown built-in scene 'fig7'"):
        builtin_scene("fig7")
    with pytest.raises(ValueError, match="fig9: unknown parameter 'depth'"):
        builtin_scene("fig9:depth=3")
    with pytest.raises(ValueError, match="fig9: distance_mm must be a number"):
        builtin_scene("fig9:distance_mm=far")
    with pytest.raises(ValueError, match="^fig9: distance_mm needs a value: distance_mm=<number>$"):
        builtin_scene("fig9:distance_mm")
    with pytest.raises(ValueError, match="^fig9: distance_mm is given twice$"):
        builtin_scene("fig9:distance_mm=700,distance_mm=800")


def test_seam_centre_line_lies_on_the_groove_bottom():
    from psvs.simulate.builtin import seam_mesh
    V, plates, groove = seam_mesh()
    x = np.linspace(-120, 120, 480)[::60]          # grid stations of the mesh
    line = seam_centre_line(x)
    for p in line:
        at_x = V[np.abs(V[:, 0] - p[0]) < 1e-9]
        lowest = at_x[np.argmin(at_x[:, 2])]
        np.testing.assert_allclose(lowest, p, atol=1e-9)
    assert len(groove) > 0 and len(plates) > len(groove)
