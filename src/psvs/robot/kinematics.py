"""Kinematics of a 6R arm from its standard Denavit-Hartenberg table, in mm and rad, NumPy only.

The simulated cell's arm is the PUMA 560 of Corke's Robotics Toolbox (``roboticstoolbox-python``'s
``models.DH.Puma560``: the same DH table and joint range, in mm here). The tests check this module against
the toolbox (table, forward kinematics, inverse kinematics). It is computed here, and not by the toolbox
at run time, because importing the toolbox alone takes 2 s on a 2-core machine (it loads matplotlib,
scipy.stats and its mobile-robot modules), the whole start-up budget of ``psvs track --handeye`` (2 s to
the first control cycle). The arm needs only forward kinematics, the Jacobian and a damped least-squares inverse.

Standard DH: link i maps frame i to frame i-1 by A_i = Rz(θ_i + offset_i) · Tz(d_i) · Tx(a_i) · Rx(α_i).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class DHChain:
    """A serial chain of revolute joints, standard DH. Arrays (n,): d and a in mm, alpha and offset in
    rad; qlim (2, n) rad, lower row then upper."""

    d: np.ndarray
    a: np.ndarray
    alpha: np.ndarray
    offset: np.ndarray
    qlim: np.ndarray

    @property
    def n(self) -> int:
        return len(self.d)

    def frames(self, q) -> np.ndarray:
        """Frames 0..n in the base frame (n + 1, 4, 4), mm: frames[i] is frame i's pose (frame 0 = base)."""
        q = np.asarray(q, float)
        if q.shape != (self.n,):
            raise ValueError(f"q must have {self.n} joint angles, got shape {q.shape}")
        th = q + self.offset
        ct, st = np.cos(th), np.sin(th)
        ca, sa = np.cos(self.alpha), np.sin(self.alpha)
        out = np.empty((self.n + 1, 4, 4))
        out[0] = np.eye(4)
        for i in range(self.n):
            link = np.array([[ct[i], -st[i] * ca[i], st[i] * sa[i], self.a[i] * ct[i]],
                             [st[i], ct[i] * ca[i], -ct[i] * sa[i], self.a[i] * st[i]],
                             [0.0, sa[i], ca[i], self.d[i]],
                             [0.0, 0.0, 0.0, 1.0]])
            out[i + 1] = out[i] @ link
        return out

    def fkine(self, q) -> np.ndarray:
        """The last frame (the flange) in the base frame, (4, 4), mm."""
        return self.frames(q)[-1]

    def jacobian(self, q) -> np.ndarray:
        """Geometric Jacobian (6, n) in the base frame: rows 0-2 the flange origin's velocity (mm/rad),
        rows 3-5 its angular velocity (rad/rad). Column i: z_(i) × (o_n − o_(i)) over z_(i), where z_(i)
        and o_(i) are frame i's z axis and origin (joint i + 1 turns about frame i's z)."""
        f = self.frames(q)
        z = f[:-1, :3, 2]
        o = f[:-1, :3, 3]
        return np.vstack([np.cross(z, f[-1, :3, 3] - o).T, z.T])


def rotation_error(r_target: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Rotation vector (3,) rad, in the base frame, that turns ``r`` (3, 3) into ``r_target`` (3, 3): the
    log of r_target · rᵀ (axis × angle, angle in [0, π])."""
    e = r_target @ r.T
    v = 0.5 * np.array([e[2, 1] - e[1, 2], e[0, 2] - e[2, 0], e[1, 0] - e[0, 1]])
    s = float(np.linalg.norm(v))
    c = 0.5 * (np.trace(e) - 1.0)
    angle = math.atan2(s, c)
    if s > 1e-12:
        return v * (angle / s)
    if c > 0:           # no rotation
        return np.zeros(3)
    # a half turn: e = 2 u uᵀ − I, u from the largest diagonal of (e + I) / 2
    m = 0.5 * (e + np.eye(3))
    i = int(np.argmax(np.diag(m)))
    u = m[:, i] / math.sqrt(max(m[i, i], 1e-300))
    return u * math.pi


def pose_error(target: np.ndarray, pose: np.ndarray, length_mm: float) -> np.ndarray:
    """(6,) error of ``pose`` against ``target`` (both (4, 4), mm): the translation over ``length_mm`` and
    the rotation vector (rad), so both parts are dimensionless."""
    return np.r_[(target[:3, 3] - pose[:3, 3]) / length_mm, rotation_error(target[:3, :3], pose[:3, :3])]


@dataclass(frozen=True)
class IKResult:
    """Joint angles (n,) rad; converged; iterations taken; the final position error (mm) and rotation
    error (rad)."""

    q: np.ndarray
    success: bool
    iterations: int
    position_error_mm: float
    rotation_error_rad: float


def ikine_lm(chain: DHChain, target, q0, *, tol_mm: float = 1e-7, tol_rad: float = 1e-10,
             max_iterations: int = 200, length_mm: float = 1000.0) -> IKResult:
    """Joint angles reaching ``target`` (4, 4, mm) from ``q0`` (n,) rad by Levenberg-Marquardt (damped
    least squares with Marquardt's adaptive damping): each step solves (JᵀJ + λI) Δq = Jᵀe, with e the
    pose error (translation over ``length_mm``, rotation vector in rad) and J the matching rows of the
    Jacobian; a step that lowers |e| is taken and λ shrinks, else λ grows. The solution is the one reached
    from q0, normally the nearest in the same arm configuration. No joint range is applied here.
    Converged when the position error ≤ ``tol_mm`` and the rotation error ≤ ``tol_rad``."""
    target = np.asarray(target, float)
    if target.shape != (4, 4) or not np.all(np.isfinite(target)):
        raise ValueError("target pose must be a finite 4x4 matrix")
    q = np.asarray(q0, float).copy()
    scale = np.r_[np.full(3, 1.0 / length_mm), np.ones(3)][:, None]

    def residual(qq):
        f = chain.fkine(qq)
        return pose_error(target, f, length_mm)

    e = residual(q)
    cost = float(e @ e)
    done = lambda err: (np.linalg.norm(err[:3]) * length_mm <= tol_mm  # noqa: E731
                        and np.linalg.norm(err[3:]) <= tol_rad)
    lam, it, stuck = 1e-3, 0, False
    while not done(e) and not stuck and it < max_iterations:
        it += 1
        j = chain.jacobian(q) * scale
        jtj, jte = j.T @ j, j.T @ e
        while True:
            q_new = q + np.linalg.solve(jtj + lam * np.eye(chain.n), jte)
            e_new = residual(q_new)
            cost_new = float(e_new @ e_new)
            if cost_new < cost:
                q, e, cost = q_new, e_new, cost_new
                lam = max(lam / 10.0, 1e-12)
                break
            lam *= 10.0
            if lam > 1e8:   # no step lowers the error: a local minimum (an unreachable pose)
                stuck = True
                break
    pos, rot = float(np.linalg.norm(e[:3]) * length_mm), float(np.linalg.norm(e[3:]))
    return IKResult(q, pos <= tol_mm and rot <= tol_rad, it, pos, rot)


#: The PUMA 560 (Unimation), standard DH, as in roboticstoolbox-python's ``models.DH.Puma560`` (Corke),
#: in mm; joint range -160..160, -45..225, -225..45, -110..170, -100..100, -266..266 degrees.
PUMA560 = DHChain(
    d=np.array([671.83, 0.0, 150.05, 431.8, 0.0, 0.0]),
    a=np.array([0.0, 431.8, 20.3, 0.0, 0.0, 0.0]),
    alpha=np.array([math.pi / 2, 0.0, -math.pi / 2, math.pi / 2, -math.pi / 2, 0.0]),
    offset=np.zeros(6),
    qlim=np.radians([[-160.0, -45.0, -225.0, -110.0, -100.0, -266.0],
                     [160.0, 225.0, 45.0, 170.0, 100.0, 266.0]]),
)
