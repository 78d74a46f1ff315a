"""The alignment guide: which screw of which mirror to turn, which way and how far, so that the twins of
every scene point land on the same rows.

A build's mirrors are glued a little off; calibration (``psvs calibrate``) measures each mirror's
(tilt a, tilt b, shift) as a rig file. Each mirror sits on a seat (:mod:`psvs.mount.seats`): a pivot and
two screws, H (trims tilt a) and V (trims tilt b). The guide finds the turns x (8,) of the eight screws
(M1 H, M1 V, ..., M4 V; clockwise seen from behind > 0) that bring the twins' rows together:

- **Row offset** of a scene point: (v_left - v_right) through the build, minus the same through the build's
  design (the same camera and lens, every mirror as designed, the box not turned). The lens's distortion
  and the plate's own small row shift are in both and cancel; what is left is what the mirrors' errors do,
  and what the screws can undo. Points: the left view's pixel grid (11 x 9) at 3 depths over the working
  range, kept where both views see them (:func:`psvs.measure.tolerance.field_points`).
- **Turns**: Gauss-Newton on the exact optics (:func:`psvs.optics.project.project_points`) and the exact
  seat (:func:`psvs.mount.seats.apply_turns`), least squares on the row offsets with a small Tikhonov
  weight toward zero turns. Turn combinations that move no twin off its partner's row (singular values of
  the row-offset Jacobian under :data:`NULL_PX_PER_TURN`, RMS px per turn of a screw of the reference
  pitch: they move both twins alike, or along their rows) cannot be told apart by the rows: the guide says
  so and takes none of them (the minimum-norm turns).
- **What calibration cannot see** (docs/calibration.md): a build that differs from the calibrated rig by a
  change no image sees (a periscope moved along its normal, the box's turn traded for mirror tilts, a rigid
  motion of frame C) gives the same images, so the same twins' rows: the turns found on the calibrated rig
  hold for the true build too, up to how the screws' effect itself differs between the two (second order).
- **Quantised** to 1/16 turn: every screw within two steps of its nearest rounding is tried (5^8
  combinations), then a descent (:func:`_quantise`); the choice has the smallest predicted largest row
  offset plus :data:`TURN_COST_PX` per turn. The offset after those turns is then computed exactly.
- **Right or refuse**: turns after which the twins would still stand more than :data:`ALIGNED_RMS_PX` RMS off
  their rows do not align the build; :func:`check_aligned` refuses them (``psvs adjust`` exits 1) rather
  than hand a builder screw turns that leave the rows where they were.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from psvs.errors import MeasurementError
from psvs.evidence import ROW_TOLERANCE_PX
from psvs.measure.tolerance import field_points
from psvs.mount.seats import DEFAULT_PITCH_MM, SCREWS, Seat, apply_turns, handedness, screw_rates
from psvs.optics.project import project_points
from psvs.optics.rig import MIRROR_NAMES, Rig

#: Turns are given in steps of this (a builder can set a screw to 1/16 of a turn by its hex key).
TURN_STEP = 1.0 / 16.0
#: The guide's thresholds and weights below are per turn of a screw of this pitch (mm): for another pitch
#: they scale with it (a turn of a 0.05 mm screw moves a contact a tenth as far), so the guide weighs the
#: same motions of the glass whatever screws the seats hold (:func:`alignment_guide` scales them).
REFERENCE_PITCH_MM = DEFAULT_PITCH_MM
#: A turn combination that moves the twins' rows by less than this (RMS px per turn) is not seen.
NULL_PX_PER_TURN = 0.02
#: Tikhonov weight toward zero turns, px (RMS) per turn: small against any screw that matters.
REGULARISE_PX_PER_TURN = 0.01
#: In the rounding to 1/16 turn, a turn in all (any screw) costs as much as this many px of row offset.
TURN_COST_PX = 0.3
#: px RMS: turns after which the twins stand further off their rows than this (predicted) do not align the
#: build (the self-check's tolerance): the guide says so instead of them.
ALIGNED_RMS_PX = ROW_TOLERANCE_PX
#: The rounding tries every screw this many 1/16-turn steps either side of its nearest rounding.
SEARCH_STEPS = 2
#: Along the turns the rows cannot see, lattice points up to this far (turns) are tried, the best few descended.
NULL_REACH_TURNS = 1.0
NULL_STARTS = 8
NULL_MOST = 4
#: The order of the eight turns.
SCREW_ORDER = tuple((m, s) for m in MIRROR_NAMES for s in SCREWS)


@dataclass(frozen=True)
class ScrewTurn:
    """One screw's turn: ``turns`` (a multiple of 1/16, clockwise seen from behind > 0), and what one turn
    does (small angles): ``rad_per_turn`` of its tilt (``tilt`` 'a' about the vertical or 'b' out of
    vertical, the rig's sign convention) and ``shift_mm_per_turn`` along the normal at the anchor."""

    mirror: str
    screw: str
    tilt: str
    turns: float
    rad_per_turn: float
    shift_mm_per_turn: float

    @property
    def direction(self) -> str:
        return "clockwise" if self.turns > 0 else "counter-clockwise" if self.turns < 0 else "none"


@dataclass(frozen=True)
class AlignmentGuide:
    """The guide's result. ``turns``: all eight screws in :data:`SCREW_ORDER`; ``before_px``/``after_px``:
    (largest, RMS) |row offset| over the ``n_points`` field points before and after the quantised turns,
    px; ``after_unquantised_px``: the same for the turns before rounding; ``null_space``: unit turn
    combinations (each (8,) in SCREW_ORDER) that move no row; ``singular_px``: RMS px per turn along each
    singular direction, largest first; ``weighed``: the indices of the :func:`working_points` the offsets
    are over (both views see them, and still do as the screws turn); ``lost_after``: how many of those a view
    misses after the quantised turns (a turned mirror's edge moves into the field): ``after_px`` is over
    the others."""

    turns: tuple[ScrewTurn, ...]
    before_px: tuple[float, float]
    after_px: tuple[float, float]
    after_unquantised_px: tuple[float, float]
    null_space: tuple[tuple[float, ...], ...]
    singular_px: tuple[float, ...]
    near_mm: float
    far_mm: float
    n_points: int
    pitch_mm: float
    weighed: tuple[int, ...] = ()
    lost_after: int = 0

    @property
    def aligned(self) -> bool:
        """Whether the turns bring the twins within :data:`ALIGNED_RMS_PX` RMS of their rows (predicted)."""
        return bool(self.after_px[1] <= ALIGNED_RMS_PX)

    def refusal(self) -> str:
        """Why these turns do not align the build ("" when they do): the offsets before and after."""
        if self.aligned:
            return ""
        said = (f"the screws cannot bring the twins onto their rows: after the turns (predicted) they stand "
                f"{self.after_px[1]:.2f} px RMS off them (largest {self.after_px[0]:.2f} px; before "
                f"{self.before_px[1]:.2f} px RMS), beyond {ALIGNED_RMS_PX:g} px: ")
        if self.after_unquantised_px[1] <= ALIGNED_RMS_PX:
            return said + (f"1/16 of a turn of these screws ({self.pitch_mm:g} mm pitch) is too coarse a step for "
                           f"the tilts (unrounded turns would leave {self.after_unquantised_px[1]:.2f} px): finer "
                           "screws")
        return said + ("what moved is not what the seats' screws trim (a mirror's shift, the box), or the seats are "
                       "not these; calibrate again, or check the mount")

    @property
    def turns_by_mirror(self) -> dict[str, tuple[float, float]]:
        """``{mirror: (turns of H, turns of V)}``, as :func:`psvs.mount.seats.apply_turns` takes them."""
        out = {m: [0.0, 0.0] for m in MIRROR_NAMES}
        for t in self.turns:
            out[t.mirror][SCREWS.index(t.screw)] = t.turns
        return {m: (h, v) for m, (h, v) in out.items()}


def check_aligned(g: AlignmentGuide) -> AlignmentGuide:
    """``g`` itself when its turns align the build (:attr:`AlignmentGuide.aligned`), else MeasurementError
    saying by how much they do not (:meth:`AlignmentGuide.refusal`)."""
    if not g.aligned:
        raise MeasurementError(g.refusal())
    return g


def designed_twin(rig: Rig) -> Rig:
    """The build's design: the same camera, every mirror as designed, the box not turned."""
    return rig.designed_mirrors()


def twin_rows_px(rig: Rig, points_mm: np.ndarray) -> np.ndarray:
    """v_left - v_right (N,) px of scene points (N, 3) mm through ``rig``; NaN where a view misses one."""
    left, _ = project_points(points_mm, rig, "left")
    right, _ = project_points(points_mm, rig, "right")
    return left[:, 1] - right[:, 1]


def row_offsets_px(rig: Rig, points_mm: np.ndarray) -> np.ndarray:
    """The twins' row offset (N,) px of scene points (N, 3) mm: :func:`twin_rows_px` through the build
    minus through its :func:`designed_twin` (0 for a build as designed)."""
    return twin_rows_px(rig, points_mm) - twin_rows_px(designed_twin(rig), points_mm)


def working_points(rig: Rig, near_mm: float, far_mm: float) -> np.ndarray:
    """(N, 3) mm: the field points the guide weighs (11 x 9 pixels of the left view at 3 depths)."""
    return field_points(designed_twin(rig), near_mm, far_mm, n_u=11, n_v=9, n_z=3)


def _stats(r: np.ndarray) -> tuple[float, float]:
    r = r[np.isfinite(r)]
    return float(np.max(np.abs(r))), float(np.sqrt(np.mean(r ** 2)))


def _as_dict(x: np.ndarray) -> dict[str, tuple[float, float]]:
    return {m: (float(x[2 * k]), float(x[2 * k + 1])) for k, m in enumerate(MIRROR_NAMES)}


def alignment_guide(built: Rig, seats: dict[str, Seat], near_mm: float = 400.0, far_mm: float = 1200.0,
                    iterations: int = 4) -> AlignmentGuide:
    """The screw turns that bring the twins of ``built`` (a calibrated rig) onto the same rows over
    ``near_mm`` .. ``far_mm`` (see the module's notes); ``seats`` from :func:`psvs.mount.seats.seats_for`
    on the nominal design."""
    missing = [m for m in MIRROR_NAMES if m not in seats]
    if missing:
        raise ValueError(f"seats must hold all four mirrors, missing {', '.join(missing)}")
    pts = working_points(built, near_mm, far_mm)
    base = twin_rows_px(designed_twin(built), pts)
    r0 = twin_rows_px(built, pts) - base
    keep = np.isfinite(r0)
    idx = np.flatnonzero(keep)
    if keep.sum() < 10:
        raise ValueError(f"the views share too few field points ({int(keep.sum())}) over {near_mm}-{far_mm} mm")
    pts, base, r0 = pts[keep], base[keep], r0[keep]

    def residual(x):
        return twin_rows_px(apply_turns(built, seats, _as_dict(x)), pts) - base

    k = np.array([seats[mirror].pitch_mm for mirror, _ in SCREW_ORDER]) / REFERENCE_PITCH_MM
    J = _jacobian(residual, len(SCREW_ORDER), TURN_STEP / k)     # steps of the same travel on every screw
    steady = np.all(np.isfinite(J), axis=1)     # a point a mirror's edge cuts off as the screws turn: not weighed
    if steady.sum() < 10:
        raise ValueError(f"too few field points ({int(steady.sum())}) stay in both views as the screws turn")
    pts, base, r0, J, idx = pts[steady], base[steady], r0[steady], J[steady], idx[steady]
    m = len(pts)
    J_ref = J / k                                # px per turn of a screw of the reference pitch
    _, sv, vt = np.linalg.svd(J_ref / np.sqrt(m), full_matrices=False)
    seen = sv >= NULL_PX_PER_TURN
    A = J_ref @ vt[seen].T                               # the turns the rows see, in their own basis
    y = np.zeros(int(seen.sum()))
    lam = m * REGULARISE_PX_PER_TURN ** 2
    r = r0
    for _ in range(iterations):
        ok = np.isfinite(r)
        y = np.linalg.solve(A[ok].T @ A[ok] + lam * np.eye(len(y)), A[ok].T @ (A[ok] @ y - r[ok]))
        r = residual(vt[seen].T @ y / k)
    x_cont = vt[seen].T @ y / k
    x = _quantise(x_cont, r, J, vt[~seen] / k, turn_cost_px=TURN_COST_PX * k)
    after = residual(x) if np.any(x) else r0
    null = vt[~seen] / k
    null /= np.linalg.norm(null, axis=1, keepdims=True)
    return AlignmentGuide(_screw_turns(built, seats, x), _stats(r0), _stats(after), _stats(r),
                          tuple(tuple(float(c) for c in v) for v in null), tuple(float(s) for s in sv * k.mean()),
                          float(near_mm), float(far_mm), m, float(seats["m1"].pitch_mm), tuple(int(i) for i in idx),
                          int(np.sum(~np.isfinite(after))))


def _jacobian(residual, n: int, h) -> np.ndarray:
    """(M, n) px per turn: central differences of ``residual`` at zero turns, steps of ``h`` turn (a number,
    or (n,): one per screw)."""
    h = np.broadcast_to(np.asarray(h, dtype=float), (n,))
    cols = []
    for j in range(n):
        e = np.zeros(n)
        e[j] = h[j]
        cols.append((residual(e) - residual(-e)) / (2 * h[j]))
    return np.column_stack(cols)


def _quantise(x: np.ndarray, r: np.ndarray, J: np.ndarray, null: np.ndarray | None = None,
              step: float = TURN_STEP, turn_cost_px=TURN_COST_PX) -> np.ndarray:
    """Turns on the 1/16 lattice near ``x`` (n,) whose predicted row offsets r + J (x_q - x) have the
    smallest cost: the largest |offset| (px) plus ``turn_cost_px`` per turn (a number, or (n,): one per screw;
    :data:`TURN_COST_PX` scaled with each screw's pitch by the caller). Every screw within
    :data:`SEARCH_STEPS` steps of its nearest rounding is tried (5^8 combinations); so are the roundings of
    points moved from ``x`` along the turns the rows cannot see (``null`` (k, n), rows of unit length in turns
    of the reference pitch; up to :data:`NULL_REACH_TURNS` of them each way), since a lattice point that fits
    may lie along them far from ``x``; then a descent moves one to three screws by one step while the cost
    falls, from the best few. The best may leave a screw off its rounding where others make up for its step
    better."""
    ok = np.isfinite(r)
    r, J = r[ok], J[ok]
    near = np.round(x / step)

    def cost(xq):
        return np.abs(r + (xq - x) @ J.T).max(axis=-1) + (np.abs(xq) * turn_cost_px).sum(axis=-1)

    offsets = np.arange(-SEARCH_STEPS, SEARCH_STEPS + 1, dtype=float)
    grid = np.stack(np.meshgrid(*[offsets] * len(x), indexing="ij"), axis=-1).reshape(-1, len(x))
    best, now = near * step, float(cost(near * step))
    for chunk in np.array_split(grid, max(1, len(grid) // 16384)):
        c = cost((near + chunk) * step)
        k = int(np.argmin(c))
        if c[k] < now:
            best, now = (near + chunk[k]) * step, float(c[k])
    starts = [best]
    if null is not None and len(null):
        null = null[:NULL_MOST]                      # 17^k points: at most 17^4 (the shipped rigs have 3)
        reach = np.arange(-NULL_REACH_TURNS, NULL_REACH_TURNS + 1e-9, 2 * step)
        coef = np.stack(np.meshgrid(*[reach] * len(null), indexing="ij"), axis=-1).reshape(-1, len(null))
        cand = np.unique(np.round((x + coef @ null) / step), axis=0) * step
        c = np.concatenate([cost(chunk) for chunk in np.array_split(cand, max(1, len(cand) // 4096))])
        starts += list(cand[np.argsort(c)[:NULL_STARTS]])
    moves = _moves(len(x)) * step
    out, out_cost = best, now
    for xq in starts:
        xq, c_now = _descend(xq, float(cost(xq)), moves, cost)
        if c_now < out_cost - 1e-12:
            out, out_cost = xq, c_now
    return out


def _descend(xq: np.ndarray, now: float, moves: np.ndarray, cost) -> tuple[np.ndarray, float]:
    """Move by the best of ``moves`` while the cost falls (at most 200 moves)."""
    for _ in range(200):
        c = cost(xq[None, :] + moves)
        k = int(np.argmin(c))
        if c[k] >= now - 1e-9:
            break
        xq, now = xq + moves[k], float(c[k])
    return xq, now


def _moves(n: int, most: int = 3) -> np.ndarray:
    """(K, n): every change of one to ``most`` of n screws by one step each way."""
    out = []
    for k in range(1, most + 1):
        for idx in itertools.combinations(range(n), k):
            for signs in itertools.product((-1.0, 1.0), repeat=k):
                e = np.zeros(n)
                e[list(idx)] = signs
                out.append(e)
    return np.array(out)


def _screw_turns(built: Rig, seats: dict[str, Seat], x: np.ndarray) -> tuple[ScrewTurn, ...]:
    out = []
    for k, (mirror, screw) in enumerate(SCREW_ORDER):
        rate = screw_rates(seats[mirror], handedness(built, mirror))[screw]
        j = SCREWS.index(screw)
        out.append(ScrewTurn(mirror, screw, "ab"[j], float(x[k]), rate.tilt_rad_per_turn[j], rate.shift_mm_per_turn))
    return tuple(out)
