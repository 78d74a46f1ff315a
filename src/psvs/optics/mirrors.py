"""Where the four mirrors and the two faces of the M1 plate are, for a :class:`~psvs.optics.rig.Rig`.

With omega_1 the angle between a mirror and the optical axis, M1 (front face through (0, 0, c1)) has the
in-plane axis s1 = (sin w, 0, cos w) and reflects the axis into r1 = (sin 2w, 0, cos 2w); M4 is parallel
to M1 and crosses that reflected axis at x = +b/2. M2 and M3 are their mirror images about the YZ plane
(M2 through (0, 0, c2), M3 at x = -b/2). The plate's back face is the front face moved by d along the
direction of propagation. For w = 45 deg: M1: z = x + c1, M4: z = x + c1 - b/2, M2: z = c2 - x,
M3: z = c2 - b/2 - x.

A real build (:class:`~psvs.optics.rig.MirrorError`, ``box_rotation_rad``): each designed mirror is turned
about its anchor, first about +Y, then about its in-plane horizontal axis, and moved along its normal; the
plate's back face follows its front face (parallel faces, thickness d). Then the whole box turns about O.
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from psvs.optics.rig import Rig
from psvs.optics.surfaces import Plane
from psvs.transforms import matrix_from_rotvec

#: The two views of the complex image: "left" (transmitted through the M1 plate), "right" (reflected).
VIEWS = ("left", "right")


def mirror_planes(rig: Rig) -> dict[str, Plane]:
    """All optical surfaces of the rig: ``m1`` (coated front face), ``m1_back``, ``m2``, ``m3``, ``m4``
    (computed once per mirror set: every ray trace asks for them)."""
    return dict(_planes(rig.mirrors))


@lru_cache(maxsize=64)
def _planes(m) -> dict[str, Plane]:
    w = m.angle_rad
    c1, c2, half_b = m.m1_axis_distance_mm, m.m2_axis_distance_mm, 0.5 * m.baseline_mm
    sw, cw, s2w, c2w = math.sin(w), math.cos(w), math.sin(2 * w), math.cos(2 * w)

    s1 = np.array([sw, 0.0, cw])
    n1 = np.array([cw, 0.0, -sw])     # faces the camera
    s2 = np.array([-sw, 0.0, cw])
    n2 = np.array([-cw, 0.0, -sw])    # faces the camera (through the plate)
    a1 = np.array([0.0, 0.0, c1])
    a2 = np.array([0.0, 0.0, c2])
    reach = half_b / s2w               # path length along the reflected axis from M1 (M2) to M4 (M3)
    a4 = a1 + reach * np.array([s2w, 0.0, c2w])
    a3 = a2 + reach * np.array([-s2w, 0.0, c2w])
    ext = m.extent
    designed = {
        "m1": Plane("m1", a1, n1, s1, ext("m1")),
        "m2": Plane("m2", a2, n2, s2, ext("m2")),
        "m3": Plane("m3", a3, -n2, s2, ext("m3")),
        "m4": Plane("m4", a4, -n1, s1, ext("m4")),
    }
    if m.as_designed:
        planes = designed
    else:
        box = matrix_from_rotvec(m.box_rotation_rad)
        planes = {}
        for name, p in designed.items():
            err = m.error(name)
            turn = _tilt_matrix(err.tilt_rad, p.s_axis)
            planes[name] = p.moved(turn, p.point, err.shift_mm).moved(box, np.zeros(3))
    front = planes["m1"]
    back = Plane("m1_back", front.point - m.plate_thickness_mm * front.normal, front.normal, front.s_axis,
                 front.extent, front.t_axis)
    out = {"m1": front, "m1_back": back, "m2": planes["m2"], "m3": planes["m3"], "m4": planes["m4"]}
    for plane in out.values():          # shared by every caller (cached): read-only
        for arr in (plane.point, plane.normal, plane.s_axis, plane.t_axis):
            arr.flags.writeable = False
    return out


def front_z_mm(rig: Rig) -> float:
    """Where the rig ends toward the scene: the largest Z (mm, frame C) that any of its mirrors reaches.

    A finite mirror reaches as far as the corners of its rectangle; an unbounded one (the paper's ideal
    plane, no size in the rig file) is taken at its anchor, where its path's axis crosses it (M3 at z = c2
    and M4 at z = c1 for omega_1 = 45 deg, the far mirrors). Tilts, shifts and the box's turn of a build
    are included. Light from a point at a smaller Z would have to start inside the mirror box (or behind
    the camera): no scene point is seen there, so a triangulation that lands there is not a measurement.
    """
    z = []
    for plane in mirror_planes(rig).values():
        if plane.extent is None:
            z.append(float(plane.point[2]))
            continue
        (s0, s1), (t0, t1) = plane.extent.along_mm, plane.extent.height_mm
        for s in (s0, s1):
            for t in (t0, t1):
                z.append(float(plane.point[2] + s * plane.s_axis[2] + t * plane.t_axis[2]))
    return max(z)


def check_in_front(rig: Rig, near_mm: float, name: str = "the working range's near end") -> float:
    """ValueError when a working range's near end ``near_mm`` (mm, called ``name`` in the message) lies at or
    inside the front of the rig (:func:`front_z_mm`): no scene point is seen from inside the mirror box, so a
    range that starts there searches disparities no scene can give. Returns the front (mm)."""
    front = front_z_mm(rig)
    if near_mm <= front:
        raise ValueError(f"{name} {near_mm:g} mm lies inside the rig: its mirrors reach Z = {front:.1f} mm, and no "
                         "scene point is seen nearer")
    return front


def _tilt_matrix(tilt_rad: tuple[float, float], s_axis: np.ndarray) -> np.ndarray:
    """Rotation (3, 3) of a mirror's tilt (a, b): by a about +Y, then by b about the turned s axis."""
    yaw = matrix_from_rotvec([0.0, tilt_rad[0], 0.0])
    lean = matrix_from_rotvec(tilt_rad[1] * (yaw @ s_axis))
    return lean @ yaw


def path(rig: Rig, view: str) -> list[tuple]:
    """The surfaces of one view's optical path, in the order light from the camera meets them.

    Each step is ``("reflect", plane)``, ``("refract", plane, eta)`` with eta = n_before / n_after, or
    ``("pass", plane)`` (a zero-thickness plate: the light only has to cross the face). The left view is
    *transmitted* through the M1 plate, the right view is *reflected* at its front face.
    """
    planes = mirror_planes(rig)
    if view == "right":
        return [("reflect", planes["m1"]), ("reflect", planes["m4"])]
    if view == "left":
        n = rig.mirrors.refractive_index
        if rig.mirrors.plate_thickness_mm > 0:
            steps = [("refract", planes["m1"], 1.0 / n), ("refract", planes["m1_back"], n / 1.0)]
        else:  # a zero-thickness plate still has a finite front face that the light must pass
            steps = [("pass", planes["m1"])]
        return steps + [("reflect", planes["m2"]), ("reflect", planes["m3"])]
    raise ValueError(f"view must be 'left' or 'right', got {view!r}")


def direction_map(rig: Rig, view: str) -> np.ndarray:
    """3x3 matrix R with d_out = R d_camera for a view: the product of its mirrors' reflections.

    A parallel plate changes no direction, so only the two mirrors count (R = I for parallel mirrors).
    """
    R = np.eye(3)
    for step in path(rig, view):
        if step[0] == "reflect":
            R = step[1].householder() @ R
    return R


def virtual_centre(rig: Rig, view: str) -> np.ndarray:
    """Virtual optical centre (3,), mm: O mirrored through the view's two mirrors (plate ignored).

    For omega_1 = 45 deg: O1 = (-b/2, 0, -b/2) (left), O2 = (+b/2, 0, -b/2) (right), paper III.2.
    """
    p = np.zeros((1, 3))
    for step in path(rig, view):
        if step[0] == "reflect":
            p = step[1].reflect_points(p)
    return p[0]


def virtual_baseline_mm(rig: Rig) -> float:
    """|O1 O2|, mm: the distance of the two virtual cameras (:func:`virtual_centre`, the mirrors as placed,
    pose errors included): the baseline triangulation uses, b for the paper's ideal geometry."""
    return float(np.linalg.norm(virtual_centre(rig, "left") - virtual_centre(rig, "right")))
