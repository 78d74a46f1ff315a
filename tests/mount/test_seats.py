"""The seat model (psvs.mount.seats) against independent derivations: rad/turn = pitch / lever arm from the
mirror's rectangle, and the exact turned plane against the three contacts moved along their screws."""
import math
import re
from pathlib import Path

import numpy as np
import pytest

from psvs.io.params import load_rig
from psvs.mount.seats import (
    DEFAULT_INSET,
    DEFAULT_M1_BORDER_MM,
    Seat,
    apply_turns,
    handedness,
    plane_to_error,
    screw_rates,
    seats_for,
)
from psvs.optics.design import design_mirrors
from psvs.optics.mirrors import mirror_planes
from psvs.optics.rig import MIRROR_NAMES, MirrorError
from psvs.rigs import shipped_rig_path

MV1440, CLEAR = (load_rig(shipped_rig_path(n)) for n in ("mv1440", "clear"))


@pytest.mark.parametrize("rig", [MV1440, CLEAR], ids=["mv1440", "clear"])
@pytest.mark.parametrize("pitch", [0.5, 0.35])
def test_rate_is_pitch_over_lever_arm(rig, pitch):
    """|rad/turn| = pitch / lever (the contacts (1 - 2 inset) of the width or height apart); H trims only
    tilt a, V only tilt b; the shift per turn is the pitch times the anchor's share of the lever."""
    seats = seats_for(rig, pitch_mm=pitch)
    for name in MIRROR_NAMES:
        ext = rig.mirrors.extent(name)
        w, h = ext.size_mm
        lever_h, lever_v = (1 - 2 * DEFAULT_INSET) * w, (1 - 2 * DEFAULT_INSET) * h
        t_pivot = ext.height_mm[0] + DEFAULT_INSET * h
        if name == "m1":   # M1's contacts in the middle of its borders, outside the light
            lever_v, t_pivot = h + DEFAULT_M1_BORDER_MM, ext.height_mm[0] - DEFAULT_M1_BORDER_MM / 2
        rates = screw_rates(seats[name], handedness(rig, name))
        assert abs(rates["H"].tilt_rad_per_turn[0]) == pytest.approx(pitch / lever_h, rel=1e-12)
        assert abs(rates["V"].tilt_rad_per_turn[1]) == pytest.approx(pitch / lever_v, rel=1e-12)
        assert rates["H"].tilt_rad_per_turn[1] == pytest.approx(0, abs=1e-15)
        assert rates["V"].tilt_rad_per_turn[0] == pytest.approx(0, abs=1e-15)
        s_pivot = ext.along_mm[0] + DEFAULT_INSET * w
        assert rates["H"].shift_mm_per_turn == pytest.approx(pitch * -s_pivot / lever_h, rel=1e-12)
        assert rates["V"].shift_mm_per_turn == pytest.approx(pitch * -t_pivot / lever_v, rel=1e-12)


def _tips(rig, seat, name):
    """The three contacts, mm (3, 3): where each screw's axis (through the designed contact, along the
    designed normal) meets the back of the glass as ``rig`` holds it (the box not turned)."""
    zero = rig.with_errors({n: MirrorError() for n in MIRROR_NAMES}).replace(box_rotation_rad=(0.0, 0.0, 0.0))
    d = mirror_planes(zero)[name]
    now = mirror_planes(rig.replace(box_rotation_rad=(0.0, 0.0, 0.0)))[name]
    back = now.point - seat.back_offset_mm * now.normal
    out = []
    for s, t in seat.contacts_st_mm:
        q = d.point + s * d.s_axis + t * d.t_axis - seat.back_offset_mm * d.normal
        out.append(q + ((back - q) @ now.normal) / (d.normal @ now.normal) * d.normal)
    return np.array(out), d.normal, now.normal


@pytest.mark.parametrize("turns", [(0.25, 0.0), (0.0, -0.5), (1.0, 0.75), (-2.0, 1.5)])
def test_turned_glass_rests_on_the_moved_contacts(turns):
    """Exact: after the turns the glass's back (the rig's own plane, psvs.optics.mirrors) passes through
    the pivot and the two screw tips moved by pitch x turns along their axes; the normal turns about +Y by
    the H rate (small turns) with the rig's sign."""
    build = load_rig(shipped_rig_path("mv1440_misaligned"))
    seats = seats_for(MV1440)
    for name in MIRROR_NAMES:
        tips, axis, _ = _tips(build, seats[name], name)
        tips[1:] += seats[name].pitch_mm * np.array(turns)[:, None] * axis
        turned = apply_turns(build, seats, {name: turns})
        after = mirror_planes(turned.replace(box_rotation_rad=(0.0, 0.0, 0.0)))[name]
        back = after.point - seats[name].back_offset_mm * after.normal
        assert np.abs((tips - back) @ after.normal).max() < 1e-9
        for other in MIRROR_NAMES:
            if other != name:
                assert turned.mirrors.error(other) == build.mirrors.error(other)
        assert turned.mirrors.box_rotation_rad == build.mirrors.box_rotation_rad


def test_small_turn_matches_the_small_angle_rates():
    """1/1000 turn of each screw changes (tilt a, tilt b, shift) as screw_rates says, to 0.5 %."""
    build = load_rig(shipped_rig_path("misaligned"))
    seats = seats_for(CLEAR)
    for name in MIRROR_NAMES:
        rates = screw_rates(seats[name], handedness(CLEAR, name))
        e0 = build.mirrors.error(name)
        for k, screw in enumerate("HV"):
            turns = [0.0, 0.0]
            turns[k] = 1e-3
            e1 = apply_turns(build, seats, {name: tuple(turns)}).mirrors.error(name)
            got = (np.subtract(e1.tilt_rad, e0.tilt_rad) / 1e-3, (e1.shift_mm - e0.shift_mm) / 1e-3)
            want = rates[screw]
            assert got[0][k] == pytest.approx(want.tilt_rad_per_turn[k], rel=5e-3)
            assert abs(got[0][1 - k]) < 1e-3 * abs(want.tilt_rad_per_turn[k])
            assert got[1] == pytest.approx(want.shift_mm_per_turn, rel=5e-3, abs=1e-4)


def test_clockwise_on_m1_h_turns_its_normal_about_plus_y():
    """Sign, from the geometry alone: M1's H screw (at larger s than the pivot) pushed toward the light turns
    the normal about +Y by +pitch/lever when M1's s x n is +Y, and the rig's tilt a grows by the same."""
    seats = seats_for(MV1440)
    seat = seats["m1"]
    n0 = mirror_planes(MV1440)["m1"].normal
    turned = apply_turns(MV1440, seats, {"m1": (0.01, 0.0)})
    n1 = mirror_planes(turned)["m1"].normal
    angle = math.asin(np.cross(n0, n1)[1])
    lever = seat.h_st_mm[0] - seat.pivot_st_mm[0]
    assert handedness(MV1440, "m1") == 1.0
    assert angle == pytest.approx(0.01 * seat.pitch_mm / lever, rel=1e-3)
    assert turned.mirrors.m1_error.tilt_rad[0] == pytest.approx(angle, rel=1e-9)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_plane_to_error_inverts_the_rigs_tilt(seed):
    """Random errors up to 2 deg and 2 mm on every mirror: the planes the rig builds map back to them."""
    rng = np.random.default_rng(seed)
    errors = {n: MirrorError(tuple(np.radians(rng.uniform(-2, 2, 2))), float(rng.uniform(-2, 2)))
              for n in MIRROR_NAMES}
    build = MV1440.with_errors(errors)
    zero = mirror_planes(MV1440)
    planes = mirror_planes(build)
    for n in MIRROR_NAMES:
        got = plane_to_error(zero[n], planes[n].point, planes[n].normal)
        assert np.allclose(got.tilt_rad, errors[n].tilt_rad, atol=1e-12)
        assert got.shift_mm == pytest.approx(errors[n].shift_mm, abs=1e-9)


def test_unbounded_mirrors_are_sized_by_design():
    """A rig without mirror sizes: the seats sit on design_mirrors' rectangles."""
    bare = CLEAR.with_extents({n: None for n in MIRROR_NAMES})
    sized = design_mirrors(bare, search=False).rig
    assert seats_for(bare) == seats_for(sized)


def test_bad_seats_are_refused():
    with pytest.raises(ValueError, match="not on one line"):
        Seat("m1", (0.0, 0.0), (10.0, 0.0), (20.0, 0.0), 2.0)
    with pytest.raises(ValueError, match="pitch_mm"):
        Seat("m1", (0.0, 0.0), (10.0, 0.0), (0.0, 10.0), 2.0, pitch_mm=0.0)
    with pytest.raises(ValueError, match="mirror must be one of"):
        Seat("m5", (0.0, 0.0), (10.0, 0.0), (0.0, 10.0), 2.0)
    with pytest.raises(ValueError, match="inset"):
        seats_for(MV1440, inset=0.5)
    with pytest.raises(ValueError, match="glass_mm"):
        seats_for(MV1440, glass_mm=-1.0)
    with pytest.raises(ValueError, match="no seat for mirror"):
        apply_turns(MV1440, {}, {"m1": (1.0, 0.0)})


def test_docs_table_is_the_clear_designs_seats():
    """docs/mount.md's table of the clear design's seats, as seats_for and screw_rates give them."""
    doc = (Path(__file__).resolve().parents[2] / "docs" / "mount.md").read_text()
    seats = seats_for(CLEAR)
    for name in MIRROR_NAMES:
        row = re.search(rf"^\| {name.upper()}[^|]*\|(.*)$", doc, re.M).group(1).replace("−", "-")
        nums = [float(x) for x in re.findall(r"-?\d+\.\d+", row)]
        rates = screw_rates(seats[name], handedness(CLEAR, name))
        want = [*seats[name].levers_mm, math.degrees(rates["H"].tilt_rad_per_turn[0]),
                math.degrees(rates["V"].tilt_rad_per_turn[1]), rates["H"].shift_mm_per_turn,
                rates["V"].shift_mm_per_turn]
        printed = [round(w, 1) for w in want[:2]] + [round(w, 3) for w in want[2:]]
        assert printed == nums, (name, nums, want)
