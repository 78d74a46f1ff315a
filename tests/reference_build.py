"""An independent model of a *misaligned* PSVS build for tests (omega_1 = 45 deg), sharing no code with
psvs.optics: hand-written Rodrigues rotations and 4x4 reflection matrices, OpenCV for the lens.

The designed mirrors (frame C, mm): M1 through (0, 0, c1) with unit normal (1, 0, -1)/sqrt 2 (toward the
camera), M4 through (b/2, 0, c1) parallel to M1, M2 through (0, 0, c2) with normal (-1, 0, -1)/sqrt 2, M3
through (-b/2, 0, c2) parallel to M2. The build's errors, as docs/optics.md defines them: a mirror turns
about its anchor by a about +Y, then by b about its turned in-plane horizontal axis (the horizontal
in-plane direction with +Z component), then moves by ``shift`` along its turned normal, where M1 and M2's
normals face the camera and M3 and M4's face the light coming from M2 and M1. The plate's back face is the
turned front face moved by d away from the camera. Then the whole box turns about O by a rotation vector.

Right view: two reflections, a pinhole camera whose frame is the reflected camera frame; projected with
``cv2.projectPoints`` and OpenCV's five distortion terms. Left view: the camera ray crosses the tilted
plate (the textbook displacement d sin(theta - theta_t) / cos theta_t, toward the normal's part
perpendicular to the ray), then is reflected by M2 and M3; projected by solving for the pixel with fsolve.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import fsolve


def rodrigues(axis, angle: float) -> np.ndarray:
    """Rotation matrix by ``angle`` rad about the unit ``axis`` (Rodrigues' formula)."""
    k = np.asarray(axis, float)
    k = k / np.linalg.norm(k)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def reflection(point, normal) -> np.ndarray:
    """4x4 homogeneous reflection in the plane through ``point`` with ``normal``."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    M = np.eye(4)
    M[:3, :3] -= 2 * np.outer(n, n)
    M[:3, 3] = 2 * (np.dot(point, n)) * n
    return M


@dataclass(frozen=True)
class Lens:
    """The camera: focal length f and pixel pitch (mm), principal point (px), OpenCV's five distortion terms."""
    f: float = 11.3
    pitch: float = 0.01
    centre: tuple = (319.5, 239.5)
    dist: tuple = (0, 0, 0, 0, 0)


@dataclass(frozen=True)
class Box:
    """The designed mirror box (mm): baseline b, the M1/M4 and M2/M3 axis distances c1 and c2, the M1
    plate's thickness d and refractive index n."""
    b: float = 100.0
    c1: float = 22.0
    c2: float = 44.0
    d: float = 3.0
    n: float = 1.52


class ReferenceBuild:
    """A build of ``box`` seen through ``lens``: ``errors`` maps a mirror name to its (tilt a, tilt b, shift)
    (rad, rad, mm), ``box_rotvec`` turns the whole box about O."""

    def __init__(self, lens=Lens(), box=Box(), errors=None, box_rotvec=(0.0, 0.0, 0.0)):
        self.f, self.pitch = lens.f, lens.pitch
        self.centre, self.dist = np.asarray(lens.centre, float), np.asarray(lens.dist, float)
        self.d, self.n = box.d, box.n
        b, c1, c2 = box.b, box.c1, box.c2
        r2 = 1 / math.sqrt(2)
        designed = {  # anchor, normal (facing the arriving light), in-plane horizontal axis (+Z part)
            "m1": ([0, 0, c1], [r2, 0, -r2], [r2, 0, r2]),
            "m4": ([b / 2, 0, c1], [-r2, 0, r2], [r2, 0, r2]),
            "m2": ([0, 0, c2], [-r2, 0, -r2], [-r2, 0, r2]),
            "m3": ([-b / 2, 0, c2], [r2, 0, r2], [-r2, 0, r2]),
        }
        rv = np.asarray(box_rotvec, float)
        turn = rodrigues(rv, np.linalg.norm(rv)) if np.linalg.norm(rv) > 0 else np.eye(3)
        self.planes = {}
        for name, (a, nrm, s) in designed.items():
            tilt_a, tilt_b, shift = (errors or {}).get(name, (0.0, 0.0, 0.0))
            yaw = rodrigues([0, 1, 0], tilt_a)
            R = rodrigues(yaw @ np.asarray(s, float), tilt_b) @ yaw
            normal = R @ np.asarray(nrm, float)
            point = np.asarray(a, float) + shift * normal
            self.planes[name] = (turn @ point, turn @ normal)

    # --- the lens ---------------------------------------------------------------------------------------
    def _K(self):
        fp = self.f / self.pitch
        return np.array([[fp, 0, self.centre[0]], [0, fp, self.centre[1]], [0, 0, 1.0]])

    def pixel_of_camera_dir(self, vec) -> np.ndarray:
        """Pixel (2,) of a camera-frame direction, through OpenCV's lens model."""
        uv, _ = cv2.projectPoints(np.asarray(vec, float)[None, :], np.zeros(3), np.zeros(3), self._K(), self.dist)
        return uv.reshape(2)

    def camera_dir(self, u, v) -> np.ndarray:
        """Unit camera-frame direction (3,) seen by pixel (u, v): OpenCV's projection inverted by fsolve."""
        target = np.array([u, v], float)
        guess = (target - self.centre) * self.pitch / self.f
        xy = fsolve(lambda q: self.pixel_of_camera_dir([q[0], q[1], 1.0]) - target, guess, xtol=1e-15)
        i = np.array([xy[0], xy[1], 1.0])
        return i / np.linalg.norm(i)

    # --- the views --------------------------------------------------------------------------------------
    def project_right(self, P) -> np.ndarray:
        """Pixels (N, 2) of scene points (N, 3): two reflections make a proper rigid motion M, so the
        right view is a pinhole camera at M's image of frame C; points go into that frame by M^-1."""
        M = reflection(*self.planes["m4"]) @ reflection(*self.planes["m1"])
        Minv = np.linalg.inv(M)
        pts = np.asarray(P, float) @ Minv[:3, :3].T + Minv[:3, 3]
        uv, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), self._K(), self.dist)
        return uv.reshape(-1, 2)

    def left_line(self, u, v):
        """(point, direction) of the left view's ray toward the scene for pixel (u, v)."""
        i = self.camera_dir(u, v)
        p1, N = self.planes["m1"]
        N = -N                                         # the plate normal along the light
        cos_th = float(i @ N)
        th = math.acos(cos_th)
        th_t = math.asin(math.sin(th) / self.n)
        delta = self.d * math.sin(th - th_t) / math.cos(th_t)
        perp = N - cos_th * i
        e = perp / np.linalg.norm(perp) if np.linalg.norm(perp) > 0 else np.zeros(3)
        o = delta * e                                  # the displaced line through O's image, direction i
        M = reflection(*self.planes["m3"]) @ reflection(*self.planes["m2"])
        return M[:3, :3] @ o + M[:3, 3], M[:3, :3] @ i

    def project_left(self, P) -> np.ndarray:
        P = np.asarray(P, float)
        M = reflection(*self.planes["m3"]) @ reflection(*self.planes["m2"])
        Minv = np.linalg.inv(M)

        def residual(uv):
            o, _ = self.left_line(*uv)
            return self.pixel_of_camera_dir(Minv[:3, :3] @ (P - o)) - uv

        guess = self.pixel_of_camera_dir(Minv[:3, :3] @ P + Minv[:3, 3])
        uv, info, ok, msg = fsolve(residual, guess, xtol=1e-14, full_output=True)
        assert ok == 1, msg
        return uv
