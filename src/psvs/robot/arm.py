"""A PUMA-family 6R arm in mm: forward/inverse kinematics and a rate-limited joint servo.

The kinematics are the PUMA 560 of roboticstoolbox-python's ``Puma560`` (standard DH, Corke), computed by
psvs.robot.kinematics (checked against the toolbox in the tests). The paper's PUMA 761 is the same
Unimation PUMA family (a larger 700-series arm with the same 6R layout: a shoulder, an elbow and a
spherical wrist), so a tracking loop tuned here carries over with the 761's DH table.

The servo stands in for the joint controller: every control cycle receives one joint set-point and
interpolates toward it at ``servo_rate_hz`` with the joint velocity and acceleration limits enforced,
braking before the joint-range limits: the joints never jump, whatever the set-points do.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from psvs.robot.kinematics import PUMA560, DHChain, ikine_lm


@dataclass(frozen=True)
class ArmLimits:
    """Joint limits: range (2, 6) rad (the toolbox's PUMA 560 table by default), speed qd_max (6,) rad/s,
    acceleration qdd_max (6,) rad/s^2, and the joint servo rate (Hz). The speed and acceleration limits
    are conservative values for seam tracking (well under the PUMA's rated joint speeds)."""

    qd_max: tuple = (1.0, 1.0, 1.0, 2.0, 2.0, 2.0)
    qdd_max: tuple = (4.0, 4.0, 4.0, 8.0, 8.0, 8.0)
    servo_rate_hz: float = 500.0
    qlim: np.ndarray | None = field(default=None, compare=False)

    def __post_init__(self):
        for name in ("qd_max", "qdd_max"):
            v = np.asarray(getattr(self, name), float)
            if v.shape != (6,) or not np.all(np.isfinite(v)) or np.any(v <= 0):
                raise ValueError(f"{name} must be six positive numbers, got {getattr(self, name)!r}")
        if not (math.isfinite(self.servo_rate_hz) and self.servo_rate_hz > 0):
            raise ValueError(f"servo_rate_hz must be > 0, got {self.servo_rate_hz!r}")


@dataclass(frozen=True)
class ServoStep:
    """Joint state after one control period: q (6,) rad, qd (6,) rad/s, the largest |qdd| reached
    (6,) rad/s^2, and whether a limit (speed, acceleration or range) bound the motion."""

    q: np.ndarray
    qd: np.ndarray
    qdd_peak: np.ndarray
    limited: bool


class Arm:
    """The arm's state over time: joint angles and speeds, kinematics in mm.

    Parameters
    ----------
    q : (6,) rad
        Initial joint angles.
    limits : ArmLimits
    chain : DHChain
        The arm's kinematics (default: the PUMA 560).
    """

    def __init__(self, q, limits: ArmLimits = ArmLimits(), chain: DHChain = PUMA560):
        self.chain = chain
        self.limits = limits
        self.qlim = np.asarray(limits.qlim if limits.qlim is not None else chain.qlim, float)
        self.q = np.asarray(q, float).copy()
        if self.q.shape != (6,):
            raise ValueError(f"q must have 6 joint angles, got shape {self.q.shape}")
        if not self.within_limits(self.q):
            raise ValueError("initial joint angles are outside the joint range")
        self.qd = np.zeros(6)
        self._last_target = None

    @cached_property
    def _qd_max(self):
        return np.asarray(self.limits.qd_max, float)

    @cached_property
    def _qdd_max(self):
        return np.asarray(self.limits.qdd_max, float)

    def within_limits(self, q) -> bool:
        """Whether every joint angle of ``q`` (6,) rad lies within the arm's joint limits (1e-9 rad of slack)."""
        return bool(np.all(q >= self.qlim[0] - 1e-9) and np.all(q <= self.qlim[1] + 1e-9))

    def fkine(self, q=None) -> np.ndarray:
        """flange2base (4, 4), mm, at joint angles q (default: the current ones)."""
        return self.chain.fkine(self.q if q is None else np.asarray(q, float))

    def ikine(self, flange2base: np.ndarray, q0=None, max_step_rad: float | None = None) -> np.ndarray:
        """Joint angles (6,) rad reaching ``flange2base`` (4, 4, mm): Levenberg-Marquardt from ``q0``
        (default: the current joints), so the solution is the one nearest it, in the same arm
        configuration. ValueError when unreachable, outside the joint range, or (``max_step_rad``) when
        the solution is more than that from ``q0`` in any joint: another configuration, a joint-space jump."""
        q0 = self.q if q0 is None else np.asarray(q0, float)
        sol = ikine_lm(self.chain, flange2base, q0)
        if not sol.success:
            raise ValueError(f"pose unreachable: inverse kinematics stopped {sol.position_error_mm:.3g} mm and "
                             f"{np.degrees(sol.rotation_error_rad):.3g} deg from it")
        q = np.asarray(sol.q, float)
        q = q0 + (q - q0 + np.pi) % (2 * np.pi) - np.pi   # the same angle nearest q0
        if not self.within_limits(q):
            raise ValueError("pose needs joint angles outside the joint range")
        if max_step_rad is not None and np.max(np.abs(q - q0)) > max_step_rad:
            raise ValueError(f"inverse kinematics jumped {np.max(np.abs(q - q0)):.2f} rad in joint space "
                             "(another arm configuration)")
        return q

    def servo(self, q_target, period_s: float) -> ServoStep:
        """Move toward ``q_target`` for one control period. The reference is the cubic (Hermite) from the
        current joints and speeds to the target, reached with the set-points' own speed (target minus the
        previous target, over the period): position and speed stay continuous across cycles. Each servo
        tick follows it with |qd| <= qd_max, |qdd| <= qdd_max, braking so that no joint passes its range
        limit."""
        q_target = np.asarray(q_target, float)
        last = getattr(self, "_last_target", None)
        v_end = np.zeros(6) if last is None else (q_target - last) / period_s
        self._last_target = q_target
        n = max(1, int(round(period_s * self.limits.servo_rate_hz)))
        dt = period_s / n
        q0, v0 = self.q.copy(), self.qd.copy()
        peak = np.zeros(6)
        limited = False
        for k in range(1, n + 1):
            tau = k / n
            h00, h10, h01, h11 = (2 * tau**3 - 3 * tau**2 + 1, tau**3 - 2 * tau**2 + tau, -2 * tau**3 + 3 * tau**2,
                                  tau**3 - tau**2)
            ref = h00 * q0 + h10 * period_s * v0 + h01 * q_target + h11 * period_s * v_end
            v = (ref - self.q) / dt
            v_lim = np.clip(v, -self._qd_max, self._qd_max)
            # brake before the range limits: v^2 <= 2 a (distance to the limit)
            room_hi = self._brake_speed(self.qlim[1] - self.q, dt)
            room_lo = -self._brake_speed(self.q - self.qlim[0], dt)
            v_lim = np.clip(v_lim, room_lo, room_hi)
            # one scale for all joints (coordinated motion): a saturated joint slows the others with it,
            # so the tool stays on its path instead of wandering off it joint by joint
            dv = v_lim - self.qd
            big = np.abs(dv) > 1e-15
            scale = min(1.0, float(np.min(self._qdd_max[big] * dt / np.abs(dv[big])))) if big.any() else 1.0
            a = dv * scale / dt
            new_qd = self.qd + a * dt
            limited |= bool(np.any(np.abs(new_qd - v) > 1e-9))
            peak = np.maximum(peak, np.abs(a))
            # the braking speed is exact only in continuous time: the last tick may not pass the limit
            self.q = np.clip(self.q + new_qd * dt, self.qlim[0], self.qlim[1])
            self.qd = new_qd
        return ServoStep(self.q.copy(), self.qd.copy(), peak, limited)

    def _brake_speed(self, room: np.ndarray, dt: float) -> np.ndarray:
        """Fastest speed (6,) from which ticks of dt braking at qdd_max stop within ``room`` (rad): the
        discrete form of v^2 = 2 a d, v = a dt (sqrt(2 d / (a dt^2) + 1/4) - 1/2)."""
        a = self._qdd_max
        return a * dt * (np.sqrt(2 * np.clip(room, 0, None) / (a * dt * dt) + 0.25) - 0.5)

    def stop(self, period_s: float) -> ServoStep:
        """One control period of braking toward rest at the acceleration limits."""
        n = max(1, int(round(period_s * self.limits.servo_rate_hz)))
        dt = period_s / n
        peak = np.zeros(6)
        for _ in range(n):
            a = np.clip(-self.qd / dt, -self._qdd_max, self._qdd_max)
            new_qd = self.qd + a * dt
            self.q = self.q + new_qd * dt
            self.qd = new_qd
            peak = np.maximum(peak, np.abs(a))
        self._last_target = None
        return ServoStep(self.q.copy(), self.qd.copy(), peak, True)
