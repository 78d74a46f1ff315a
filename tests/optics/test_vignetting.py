"""A layout that vignettes is a build; one that blocks most of a view is not (issue 41: every measuring command
refused a calibrated build whose glass met another beam at a corner). The image each view loses
(psvs.optics.obstruction.blocked_shares) against an independent count: each chief ray's path cast with trimesh
against meshes of the glass; and against the renderer's dark pixels."""
import numpy as np
import pytest
import trimesh

from psvs import default_rig
from psvs.errors import RigGeometryError
from psvs.io.params import save_rig
from psvs.optics.design import MAX_BLOCKED_SHARE, design_mirrors
from psvs.optics.layout_check import check_clear, forget
from psvs.optics.mirrors import mirror_planes
from psvs.optics.obstruction import blocked_shares
from psvs.optics.trace import trace_pixels
from tests.support.cli import run

#: (name, rig changes): layouts that lose part of one view (M2 set nearer M1 than the default's 44 mm, so the
#: plate's far end reaches into M2's beam; M2 set far, so that its end reaches the left view's outgoing beam)
VIGNETTING = {"M2 near the plate": dict(m2_axis_distance_mm=36.0),
              "M2 far, no plate": dict(plate_thickness_mm=0.0, m1_axis_distance_mm=20.0, m2_axis_distance_mm=56.0)}
GRID = (32, 24)


@pytest.fixture(autouse=True)
def own_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("PSVS_CACHE_DIR", str(tmp_path / "cache"))
    forget()
    yield
    forget()


def _quad(corners):
    return trimesh.Trimesh(vertices=corners, faces=[[0, 1, 2], [0, 2, 3], [2, 1, 0], [3, 2, 0]], process=False)


def _solids(rig) -> dict:
    """Meshes of the glass: M2-M4 as rectangles, the M1 plate as its box (front face extruded by d)."""
    out = {}
    d = rig.mirrors.plate_thickness_mm
    for name, plane in mirror_planes(rig).items():
        if name == "m1_back":
            continue
        (s0, s1), (t0, t1) = plane.extent.along_mm, plane.extent.height_mm
        c = np.array([plane.point + s * plane.s_axis + t * plane.t_axis for s, t in ((s0, t0), (s1, t0), (s1, t1),
                                                                                   (s0, t1))])
        if name == "m1" and d > 0:
            back = c - d * plane.normal
            faces = [c, back[::-1], *[np.array([c[i], c[(i + 1) % 4], back[(i + 1) % 4], back[i]]) for i in range(4)]]
            out["plate"] = trimesh.util.concatenate([_quad(f) for f in faces])
        else:
            out["plate" if name == "m1" else name] = _quad(c)
    return out


def _counted_shares(rig, grid=GRID) -> dict:
    """The share of each view's grid pixels whose chief ray (traced through the unbounded planes) crosses a
    mesh of the glass other than the ones the segment starts or ends on."""
    w, h = rig.camera.image_size_px
    u = (np.arange(grid[0]) + 0.5) * w / grid[0] - 0.5
    v = (np.arange(grid[1]) + 0.5) * h / grid[1] - 0.5
    px = np.stack(np.meshgrid(u, v), -1).reshape(-1, 2)
    solids = _solids(rig)
    free = rig.with_extents({n: None for n in ("m1", "m2", "m3", "m4")})
    out = {}
    for view in ("left", "right"):
        hits: list = []
        rays = trace_pixels(px, free, view, hits)
        names = ["camera"] + ["plate" if p.name.startswith("m1") else p.name for p, _, _ in hits] + ["scene"]
        points = [np.zeros((len(px), 3))] + [q for _, q, _ in hits] + [rays.origins_mm + 2000.0 * rays.dirs]
        lost = np.zeros(len(px), dtype=bool)
        for a, b, p0, p1 in zip(names[:-1], names[1:], points[:-1], points[1:], strict=True):
            length = np.linalg.norm(p1 - p0, axis=1)
            dirs = (p1 - p0) / length[:, None]
            for name, mesh in solids.items():
                if name in (a, b):
                    continue
                where, ray, _ = mesh.ray.intersects_location(p0, dirs, multiple_hits=True)
                inside = np.linalg.norm(where - p0[ray], axis=1) < length[ray] - 1e-9
                lost[ray[inside]] = True
        out[view] = float(lost.mean())
    return out


@pytest.mark.parametrize("name", list(VIGNETTING))
def test_the_image_a_view_loses_is_the_meshes_count(name):
    d = design_mirrors(default_rig().replace(**VIGNETTING[name]), search=False)
    mine = blocked_shares(d.rig, grid=GRID)
    counted = _counted_shares(d.rig)
    assert 0.05 < max(mine.values()) < MAX_BLOCKED_SHARE and mine == pytest.approx(counted, abs=2 / np.prod(GRID))
    assert d.verdict == "vignetted" and d.buildable and not d.ok and d.blocked_share == blocked_shares(d.rig)


def test_a_clear_layout_loses_nothing_and_a_blocked_one_most():
    assert design_mirrors(default_rig(), search=False).blocked_share == {"left": 0.0, "right": 0.0}
    blocked = design_mirrors(default_rig().replace(baseline_mm=5.0, plate_thickness_mm=30.0), search=False)
    assert blocked.verdict == "BLOCKED" and min(blocked.blocked_share.values()) > MAX_BLOCKED_SHARE
    assert blocked.blocked_share == pytest.approx(_counted_shares(blocked.rig), abs=2 / np.prod(GRID))


def test_the_renderer_sees_the_share_dark():
    """The renderer (every pixel, its own trace of the rig's glass) leaves the lost part of the left view dark:
    a lit wall's left view is black on the share the design names."""
    from psvs.simulate.builtin import regulated_light
    from psvs.simulate.render import render
    from psvs.simulate.scene import Scene
    from psvs.simulate.textures import Noise
    d = design_mirrors(default_rig().replace(**VIGNETTING["M2 near the plate"]), search=False)
    rr = render(Scene((), regulated_light(700.0), 700.0, Noise(scale_mm=2.0, seed=1), "wall"), d.rig, supersample=1,
                seed=1)
    dark = float(np.mean(rr.left <= 0.0))
    assert dark == pytest.approx(d.blocked_share["left"], abs=0.02) and np.mean(rr.right <= 0.0) < 0.005


def test_a_vignetting_build_is_measured_and_a_blocked_one_refused(capsys, tmp_path):
    d = design_mirrors(default_rig().replace(**VIGNETTING["M2 near the plate"]), search=False)
    assert check_clear(d.rig, "rig v") is d.rig
    path = tmp_path / "vignetting.toml"
    save_rig(d.rig, path)
    code, out, _ = run(capsys, "design", "--rig", str(path))
    assert code == 1 and "Layout: vignetted (the left view loses 15 % of its image, the right 0 %: a build of it " \
                         "measures in the rest)" in out
    pairs = tmp_path / "pairs.csv"       # the second pair's left pixel where M2 blocks the left view
    pairs.write_text("u_l,v_l,u_r,v_r\n300,240,210,240\n600,240,448,240\n")
    code, _, err = run(capsys, "triangulate", "--rig", str(path), str(pairs), "-o", str(tmp_path / "p.csv"))
    assert code == 0 and "1 pair(s) lie where the rig's glass blocks a view (vignetted; row 3: (600, 240) left, " \
                         "(448, 240) right), marked invalid" in err, err
    rows = np.genfromtxt(tmp_path / "p.csv", delimiter=",", names=True)
    assert list(rows["valid"]) == [1, 0] and np.isfinite(rows["Z_mm"][0]) and np.isnan(rows["Z_mm"][1])
    blocked = default_rig().replace(baseline_mm=5.0, plate_thickness_mm=30.0)
    with pytest.raises(RigGeometryError, match=r"^rig x is no layout a build can have: the left view loses 100 % "
                                               r"of its image, the right 100 % \(more than 50 % is no build\): "):
        check_clear(blocked, "rig x")


def _cut_m3(along_mm):
    """The shipped `clear` rig (sized mirrors) with M3 cut to ``along_mm`` (its height kept)."""
    from psvs.io.params import load_rig
    from psvs.optics.rig import MirrorExtent
    rig = load_rig("clear")
    return rig.with_extents({"m3": MirrorExtent(along_mm, rig.mirrors.extent("m3").height_mm)})


def test_mirrors_sized_too_small_lose_what_the_renderer_leaves_dark(capsys, tmp_path):
    """Adversarial trial (issue 41): a rig file whose M3 is cut to a third of its length was measured through
    ('Layout: clear': the design sizes the mirrors anew and the layout check ignored the file's sizes), though a
    render through it leaves two thirds of the left view dark. The file's own sizes now count: the share they
    lose (psvs.optics.obstruction.sized_shares) is the renderer's dark share, and beyond half it is refused."""
    from psvs.optics.obstruction import sized_shares
    from psvs.simulate.builtin import regulated_light
    from psvs.simulate.render import render
    from psvs.simulate.scene import Scene
    from psvs.simulate.textures import Noise
    wall = Scene((), regulated_light(700.0), 700.0, Noise(scale_mm=2.0, seed=2), "wall")
    for along, refused in (((-27.5, -10.0), True), ((-27.5, 20.0), False)):
        rig = _cut_m3(along)
        shares = sized_shares(rig)
        rr = render(wall, rig, supersample=1, seed=2)
        assert shares["left"] == pytest.approx(float(np.mean(rr.left <= 0.0)), abs=0.03)
        assert shares["right"] == 0.0 and (shares["left"] > MAX_BLOCKED_SHARE) == refused, shares
        path = tmp_path / "cut.toml"
        save_rig(rig, path)
        code, out, _ = run(capsys, "design", "--rig", str(path), "--no-search")
        lost = f"the left view loses {100 * shares['left']:.0f} % of its image, the right 0 %"
        if refused:
            blocked = f"The rig file's mirror sizes: BLOCKED: too small for the camera's field ({lost})"
            assert code == 1 and blocked in out
            with pytest.raises(RigGeometryError, match=rf"^rig x's mirrors, as sized in it, are too small for the "
                                                       rf"camera's field: {lost} \(more than 50 % is no build\); "):
                check_clear(rig, "rig x")
        else:
            assert code == 0 and f"The rig file's mirror sizes: vignetted ({lost})" in out
            assert check_clear(rig) is rig
    assert sized_shares(default_rig()) == {"left": 0.0, "right": 0.0}      # no sizes: the paper's ideal planes
