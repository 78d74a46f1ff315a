"""psvs mount: the solid read back by independent readers (OpenCASCADE for the STEP, trimesh for the STL,
the standard library for the SVG, CSV and TOML) and checked against the optics by casting the field rays."""
from __future__ import annotations

import csv
import io
import math
import re
import tomllib
import xml.etree.ElementTree as ET

import build123d as bd
import numpy as np
import pytest
import trimesh

from psvs.io.params import load_rig
from psvs.mount.build import make_mount
from psvs.mount.check import check_mount, printable_mesh
from psvs.mount.files import read_mount
from psvs.mount.layout import CLIP_BORDER_MM, MountError, MountParams, field_segments
from psvs.mount.seats import handedness, screw_rates, seats_for
from psvs.optics.design import design_mirrors
from psvs.optics.mirrors import mirror_planes
from psvs.optics.rig import MIRROR_NAMES
from psvs.rigs import shipped_rig_path

CASES = {"default": ("default", MountParams()), "mv1440": ("mv1440", MountParams()),
         "default-cs-margin": ("default", MountParams(interface="cs", lens_diameter_mm=34.0, flange_mm=30.0,
                                                      hole_square_mm=40.0, wall_mm=2.5, clearance_mm=0.2,
                                                      margin_mm=1.0))}


@pytest.fixture(scope="module", params=list(CASES))
def made(request, tmp_path_factory):
    rig_name, params = CASES[request.param]
    rig = load_rig(shipped_rig_path(rig_name))
    m = make_mount(rig, params)
    folder = tmp_path_factory.mktemp(request.param)
    for name, data in m.files.items():
        (folder / name).write_bytes(data)
    return rig, m, folder


def _mesh(folder):
    """The written STL as trimesh reads it, nothing repaired."""
    return trimesh.load(str(folder / "mount.stl"), force="mesh")


def test_stl_is_one_closed_shell_as_written(made):
    """Read back with nothing repaired: every edge of the file used by exactly two triangles, no triangle of
    zero area, one body (OpenCASCADE's tessellation held four zero-area slivers, each a shell of its own)."""
    mesh = _mesh(made[2])
    edges = np.sort(mesh.edges, axis=1)
    _, uses = np.unique(edges, axis=0, return_counts=True)
    assert set(uses.tolist()) == {2}
    assert mesh.nondegenerate_faces().all()
    assert len(mesh.split(only_watertight=False)) == 1


def test_step_is_one_solid_of_the_parts_volume(made):
    """OpenCASCADE re-reads one solid whose volume is the layout's sum of parts (which touch, never overlap)
    and the STL's (trimesh) to the tessellation's 0.1 %."""
    _, m, folder = made
    shape = bd.import_step(str(folder / "mount.step"))
    assert len(shape.solids()) == 1
    assert shape.volume == pytest.approx(m.layout.volume_mm3, rel=1e-4)
    assert _mesh(folder).volume == pytest.approx(shape.volume, rel=1e-3)


def test_stl_is_watertight_and_no_wall_is_thin(made):
    _, m, folder = made
    mesh = _mesh(folder)
    assert mesh.is_watertight and mesh.is_volume
    # thickness measured inward from 4000 surface points of the file, not from the library's check
    pts, faces = trimesh.sample.sample_surface(mesh, 4000, seed=7)
    inward = -mesh.face_normals[faces]
    loc, idx, _ = mesh.ray.intersects_location(pts + 1e-4 * inward, inward, multiple_hits=False)
    thick = np.linalg.norm(loc - pts[idx], axis=1)
    assert thick.min() >= m.layout.params.wall_mm - 0.05


def test_no_field_ray_meets_the_mount(made):
    """>= 10 000 field rays of both views, every leg cast against the STL: none hits it before its end."""
    rig, m, folder = made
    mesh = _mesh(folder)
    design = design_mirrors(rig, margin_mm=m.layout.params.margin_mm, search=False)
    legs = field_segments(design.rig, 1200.0)
    n_rays = len(legs[0][0]) + len(legs[-1][0])
    assert n_rays >= 10_000
    hits = 0
    for p0, p1 in legs:
        d = p1 - p0
        length = np.linalg.norm(d, axis=1)
        loc, idx, _ = mesh.ray.intersects_location(p0, d / length[:, None], multiple_hits=False)
        hits += int(np.sum(np.linalg.norm(loc - p0[idx], axis=1) < length[idx] - 1e-6))
    assert hits == 0
    assert m.checks.rays == n_rays and m.checks.blocked == 0


def test_glass_lands_on_its_designed_planes(made):
    """Each pivot's apex (the mesh vertex nearest it) lies on the designed glass's back within the clearance,
    the screws' holes are open along their axes, and the library's seated-glass check agrees."""
    rig, m, folder = made
    mesh = _mesh(folder)
    planes = mirror_planes(design_mirrors(rig, margin_mm=m.layout.params.margin_mm, search=False).rig)
    for name in MIRROR_NAMES:
        seat, p = m.layout.seats[name], planes[name]
        q = [p.point + s * p.s_axis + np.array([0.0, t, 0.0]) - seat.back_offset_mm * p.normal
             for s, t in seat.contacts_st_mm]
        assert np.min(np.linalg.norm(mesh.vertices - q[0], axis=1)) < m.layout.params.clearance_mm
        origins = np.array(q[1:]) + 0.5 * p.normal
        loc, idx, _ = mesh.ray.intersects_location(origins, np.tile(-p.normal, (2, 1)), multiple_hits=False)
        depth = np.linalg.norm(loc - origins[idx], axis=1)
        assert np.all(depth > 0.5 + m.layout.params.standoff_mm + m.layout.params.plate_mm - 0.05)
        assert m.checks.glass_error_mm[name] <= m.layout.params.clearance_mm
    assert m.checks.glass_intrusion == ()


def _svg_texts(path) -> list[str]:
    root = ET.parse(path).getroot()
    return ["".join(el.itertext()).strip() for el in root.iter() if el.tag.endswith("text")]


def test_drawing_dimensions_are_the_designs(made):
    """Read the SVG's text back: every mirror's centre, angle and glass size are design_mirrors's numbers."""
    rig, m, folder = made
    texts = _svg_texts(folder / "drawing.svg")
    design = design_mirrors(rig, margin_mm=m.layout.params.margin_mm, search=False)
    border = m.layout.params.m1_border_mm
    for spec in design.mirrors:
        n = spec.name.upper()
        centre = next(t for t in texts if t.startswith(f"{n} centre"))
        got = [float(v) for v in re.findall(r"=(-?\d+\.\d+)", centre)]
        assert got == pytest.approx(spec.centre_mm, abs=0.006)
        angle = float(re.search(r"angle (-?\d+\.\d+)", next(t for t in texts if t.startswith(f"{n} angle"))).group(1))
        nx, _, nz = spec.normal           # the mirror's line in the top view is across its normal
        want = math.degrees(math.atan(-nz / nx))
        assert abs(angle) == pytest.approx(45.0, abs=0.006) and angle == pytest.approx(want, abs=0.006)
        glass = next(t for t in texts if t.startswith(f"{n} glass"))
        w, h, _ = (float(v) for v in re.findall(r"(\d+\.\d+)", glass))
        want_h = spec.extent.size_mm[1] + 2 * (border if spec.name == "m1" else CLIP_BORDER_MM)
        assert (w, h) == pytest.approx((spec.extent.size_mm[0], want_h), abs=0.006)


def test_bom_and_mount_file_read_back(made):
    """The BOM (csv) names each glass with its size; mount.toml (tomllib) holds the seats' contacts and the
    degrees per turn of each screw as seats_for and screw_rates give them; read_mount returns the seats."""
    rig, m, folder = made
    rows = list(csv.DictReader(io.StringIO((folder / "bom.csv").read_text())))
    design = design_mirrors(rig, margin_mm=m.layout.params.margin_mm, search=False).rig
    for name in MIRROR_NAMES:
        row = next(r for r in rows if r["item"] == name.upper())
        w, h, t = (float(v) for v in re.findall(r"\d+\.\d+", row["size"]))
        assert (w, h) == pytest.approx(m.layout.glass[name].size_mm, abs=0.006)
    assert "beam-splitter" in next(r for r in rows if r["item"] == "M1")["part"]
    assert int(next(r for r in rows if r["item"] == "screw")["qty"]) == 8
    data = tomllib.loads((folder / "mount.toml").read_text())
    params = m.layout.params
    seats = seats_for(design, pitch_mm=params.pitch_mm, glass_mm=params.glass_mm, m1_border_mm=params.m1_border_mm)
    for name in MIRROR_NAMES:
        rates = screw_rates(seats[name], handedness(design, name))
        got = data["seats"][name]["screws"]
        assert got["H"]["tilt_deg_per_turn"] == pytest.approx(math.degrees(rates["H"].tilt_rad_per_turn[0]), rel=1e-12)
        assert got["V"]["tilt_deg_per_turn"] == pytest.approx(math.degrees(rates["V"].tilt_rad_per_turn[1]), rel=1e-12)
    assert data["checks"]["blocked"] == 0 and data["checks"]["step_solids"] == 1
    read_params, read_seats = read_mount(folder)
    assert read_params == params and read_seats == seats


def test_blocked_design_and_light_in_m1_are_refused():
    rig = load_rig(shipped_rig_path("default"))
    with pytest.raises(MountError, match="M2 cuts through the M1 plate"):
        make_mount(rig.replace(m1_axis_distance_mm=25.0, m2_axis_distance_mm=45.0))
    with pytest.raises(MountError, match="M1's contact .* lies in the light.*--m1-border-mm"):
        make_mount(rig, MountParams(m1_border_mm=8.0))
    with pytest.raises(MountError, match="holes on a 20 mm square cut into the lens bore"):
        make_mount(rig, MountParams(interface="c", hole_square_mm=20.0))
    with pytest.raises(MountError, match="lens barrel .* reaches the M1 plate"):
        make_mount(rig, MountParams(lens_front_mm=20.0))
    with pytest.raises(MountError, match="lens barrel .* blocks the light between the mirrors"):
        make_mount(rig, MountParams(lens_front_mm=15.0))


def test_the_ray_check_names_the_part_in_the_light(made, tmp_path):
    """The mount of one rig cast against another rig's light (a wider baseline): the carriers in its way are
    named, with how many rays they stop."""
    rig, m, folder = made
    other = design_mirrors(rig.replace(baseline_mm=130.0), search=False)
    checks = check_mount(m.layout, printable_mesh(folder / "mount.stl"), field_segments(other.rig, 1200.0))
    assert checks.blocked > 100 and sum(checks.blocked_by.values()) == checks.blocked
    assert all(re.fullmatch(r"m[1-4] carrier( lower| upper)?|floor|lid|lens clamp|C?S?-?mount flange plate", k)
               for k in checks.blocked_by), checks.blocked_by
    assert any(p.startswith("the ") and "blocks" in p for p in checks.problems(m.layout))


def test_hardware_is_out_of_the_light_and_a_spring_in_it_is_named(made):
    """Eight set screws behind the carriers and eight springs' rooms are cast against the light: none is met;
    a spring's room moved onto M3's middle (in the light) is named with the rays it stops."""
    from dataclasses import replace

    from psvs.mount.check import hardware_light
    from psvs.mount.layout import Box, Cylinder
    rig, m, _ = made
    ko = m.layout.keepouts
    assert sum(isinstance(k, Cylinder) for k in ko) == 8 and sum(isinstance(k, Box) for k in ko) == 8
    assert m.checks.hardware_blocked_by == {}
    p = mirror_planes(m.layout.rig)["m3"]
    spring = next(k for k in ko if isinstance(k, Box) and k.name.startswith("M3"))
    mid = p.point + 0.5 * sum(m.layout.glass["m3"].along_mm) * p.s_axis + 20.0 * p.normal
    moved = replace(m.layout, keepouts=(replace(spring, centre=tuple(mid)),))
    legs = field_segments(design_mirrors(rig, margin_mm=m.layout.params.margin_mm, search=False).rig, 1200.0)
    by = hardware_light(moved, legs)
    assert list(by) == [spring.name] and by[spring.name] > 100


def test_boxes_overlap_agrees_with_sampled_points():
    """The separating-axis test against points sampled in one box and tested in the other (their local
    coordinates within the half sizes), on random pairs; touching boxes do not overlap."""
    from psvs.mount.layout import Box, boxes_overlap
    rng = np.random.default_rng(5)

    def box(c):
        x = rng.normal(size=3)
        x /= np.linalg.norm(x)
        z = np.cross(x, rng.normal(size=3))
        z /= np.linalg.norm(z)
        return Box("b", tuple(c), tuple(x), tuple(z), tuple(rng.uniform(1, 4, 3)))

    def inside(b, pts):
        ax = np.stack([b.x_dir, np.cross(b.z_dir, b.x_dir), b.z_dir])
        return np.all(np.abs((pts - b.centre) @ ax.T) <= np.asarray(b.size) / 2, axis=1)

    agree = 0
    for _ in range(60):
        a, b = box(np.zeros(3)), box(rng.uniform(-4, 4, 3))
        ax = np.stack([a.x_dir, np.cross(a.z_dir, a.x_dir), a.z_dir])
        pts = a.centre + (rng.uniform(-0.5, 0.5, (40000, 3)) * np.asarray(a.size)) @ ax
        sampled = bool(inside(b, pts).any())
        if sampled:
            assert boxes_overlap(a, b)           # a shared point is an overlap
        agree += boxes_overlap(a, b) == sampled
    assert agree >= 57                           # sampling may miss a sliver of overlap
    a = Box("a", (0, 0, 0), (1, 0, 0), (0, 0, 1), (2, 2, 2))
    assert not boxes_overlap(a, Box("b", (2, 0, 0), (1, 0, 0), (0, 0, 1), (2, 2, 2)))


def test_m1_strips_beside_m2s_glass_are_refused_with_a_border_that_fits():
    rig = load_rig(shipped_rig_path("default"))
    with pytest.raises(MountError, match="another mirror's glass beside its strips.*--m1-border-mm 28"):
        make_mount(rig, MountParams(m1_border_mm=18.0))
