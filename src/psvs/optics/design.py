"""Mirror design for a camera, a baseline and a working range (paper III.1 and what it leaves out).

Eqs. (1)-(8) give each mirror's length in the plane of the axis. A real rig also needs each mirror's
height for the vertical field, its position along the mirror (the footprint is not centred on the axis
point), the plate's back face (the refracted beam is shifted), and a check that no mirror, nor the
plate's thickness, blocks the other view. :func:`design_mirrors` traces the camera's whole field through
each path with unbounded mirrors, takes every surface's footprint as that mirror's rectangle, so that
the rig's field of view equals the camera's (paper, property 3), and then checks for obstructions.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from psvs.errors import RigGeometryError
from psvs.optics.field import field_pixels
from psvs.optics.mirror_length import mirror_length_eq6
from psvs.optics.mirrors import VIEWS, mirror_planes
from psvs.optics.obstruction import Obstruction, blocked_shares, find_collisions, find_obstructions
from psvs.optics.rig import MIRROR_NAMES, MirrorExtent, Rig
from psvs.optics.trace import trace_pixels

#: The most of a view's image (0..1) a buildable layout may lose to the glass: beyond half, more of a view is
#: blocked than seen, a rig file that is wrong rather than a build that vignettes.
MAX_BLOCKED_SHARE = 0.5


@dataclass(frozen=True)
class MirrorSpec:
    """One mirror of a design: where it is and how big it must be (mm)."""

    name: str
    extent: MirrorExtent
    anchor_mm: tuple[float, float, float]   # where its path's optical axis crosses it
    centre_mm: tuple[float, float, float]   # centre of its rectangle (front face)
    normal: tuple[float, float, float]      # unit, facing the incoming light
    axis_distance_mm: float                 # OB of eqs. (1)-(8): path length from (virtual) O to anchor
    eq6_length_mm: float                    # AC of eq. (6) (pinhole, no plate), for comparison


@dataclass(frozen=True)
class WorkingRange:
    """What a working depth range [near, far] (mm) means for this rig."""

    near_mm: float
    far_mm: float
    disparity_px: tuple[float, float]         # ideal disparity (eq. 12) at far and near
    depth_per_px_mm: tuple[float, float]      # depth change for 1 px of disparity at near and far
    overlap_start_mm: float                   # depth where the two views' fields start to overlap


@dataclass(frozen=True)
class MirrorDesign:
    """Result of :func:`design_mirrors`: the rig with its mirror extents, a table, and the checks."""

    rig: Rig
    mirrors: tuple[MirrorSpec, ...]
    obstructions: tuple[Obstruction, ...]
    collisions: tuple[str, ...]
    working_range: WorkingRange | None
    m2_window_mm: tuple[float, float] | None = None    # clear c2 range for this c1 (see clear_m2_window)
    suggestion_mm: tuple[float, float] | None = None   # a clear (c1, c2) when this layout is not
    search_note: str = ""                              # why the search stopped short ('' it did not)
    #: share (0..1) of each view's image whose light the layout blocks (:func:`blocked_shares`; 0 when ok)
    blocked_share: dict[str, float] | None = None

    @property
    def ok(self) -> bool:
        """True when no light path is blocked and no two parts cut through each other."""
        return not self.obstructions and not self.collisions

    @property
    def buildable(self) -> bool:
        """True when a build can have this layout: each view loses at most :data:`MAX_BLOCKED_SHARE` of its
        image to the glass (:attr:`blocked_share`). A layout that is not :attr:`ok` but buildable *vignettes*:
        a build of it measures in the rest of its field (each traced pixel's path checked), as real builds
        whose glass meets another beam at a corner do."""
        return self.ok or max((self.blocked_share or {"": 1.0}).values()) <= MAX_BLOCKED_SHARE

    @property
    def verdict(self) -> str:
        """``'clear'``, ``'vignetted'`` (not :attr:`ok`, :attr:`buildable`) or ``'BLOCKED'``."""
        return "clear" if self.ok else "vignetted" if self.buildable else "BLOCKED"

    def share_words(self) -> str:
        """The image each view loses, in words (:func:`share_words`)."""
        return share_words(self.blocked_share or {})

    @property
    def problems(self) -> list[str]:
        """One line per obstruction or collision (empty when :attr:`ok`)."""
        return [str(o) for o in self.obstructions] + list(self.collisions)


def share_words(shares: dict[str, float]) -> str:
    """The image each view loses (``{'left': 0..1, 'right': 0..1}``), in words (e.g. 'the left view loses 15 % of
    its image, the right 0 %')."""
    return (f"the left view loses {100 * shares.get('left', 0.0):.0f} % of its image, the right "
            f"{100 * shares.get('right', 0.0):.0f} %")


def footprint_extents(rig: Rig, pixels_px: np.ndarray, margin_mm: float = 0.0) -> dict[str, MirrorExtent]:
    """Bounding rectangles of the field's footprint on each mirror (unbounded mirrors traced), mm.

    M1's rectangle covers both its coated front face and the plate's back face.
    """
    free = rig.with_extents({n: None for n in MIRROR_NAMES})
    local: dict[str, list] = {n: [] for n in MIRROR_NAMES}
    for view in VIEWS:
        hits: list = []
        trace_pixels(pixels_px, free, view, hits)
        for plane, pts, _ in hits:
            local[plane.name.removesuffix("_back")].append(plane.local(pts))
    out = {}
    for name, chunks in local.items():
        st = np.concatenate(chunks)
        if not np.all(np.isfinite(st)):
            raise RigGeometryError(f"part of the camera's field never reaches {name.upper()}: "
                                   f"omega_1 must exceed the half field of view")
        lo, hi = st.min(axis=0) - margin_mm, st.max(axis=0) + margin_mm
        out[name] = MirrorExtent((float(lo[0]), float(hi[0])), (float(lo[1]), float(hi[1])))
    return out


def working_range(rig: Rig, near_mm: float, far_mm: float) -> WorkingRange:
    """Disparity range, depth resolution and the start of the views' overlap for depths near..far (mm)."""
    if not 0 < near_mm < far_mm:
        raise ValueError(f"working range must satisfy 0 < near < far, got near={near_mm!r}, far={far_mm!r}")
    cam, b, zv = rig.camera, rig.mirrors.baseline_mm, rig.virtual_z_mm
    f, px = cam.focal_length_mm, cam.pixel_pitch_mm[0]
    disp = [b * f / (z - zv) / px for z in (far_mm, near_mm)]
    res = [(z - zv) ** 2 * px / (b * f) for z in (near_mm, far_mm)]
    overlap = zv + 0.5 * b / math.tan(cam.half_fov_rad[0])
    return WorkingRange(near_mm, far_mm, (disp[0], disp[1]), (res[0], res[1]), overlap)


def design_mirrors(rig: Rig, *, margin_mm: float = 0.0, near_mm: float | None = None,
                   far_mm: float | None = None, search: bool = True) -> MirrorDesign:
    """Size all four mirrors for the rig's camera and baseline and check the layout.

    Parameters
    ----------
    rig : Rig
        Camera, baseline, mirror positions c1, c2, angle and plate; any extents in it are replaced.
    margin_mm : float
        Extra border on every side of every mirror, mm (e.g. half the lens's entrance pupil).
    near_mm, far_mm : float, optional
        Working depth range, mm, for the disparity and resolution summary.
    search : bool
        Also find the clear range of M2 positions for this c1 and, when the layout is blocked, suggest a
        clear (c1, c2) (:func:`clear_m2_window`, :func:`suggest_layout`).

    Returns
    -------
    MirrorDesign
        ``rig`` with the designed extents, one :class:`MirrorSpec` per mirror, and ``obstructions``
        (empty when every path is clear).

    Examples
    --------
    >>> from psvs import default_rig
    >>> d = design_mirrors(default_rig(), search=False)
    >>> [(s.name, round(s.extent.width_mm, 2), round(s.eq6_length_mm, 2)) for s in d.mirrors]
    [('m1', 21.26, 19.16), ('m2', 37.7, 38.32), ('m3', 81.24, 81.86), ('m4', 62.7, 62.7)]
    >>> d.ok, d.problems
    (True, [])
    >>> blocked = design_mirrors(default_rig().replace(m1_axis_distance_mm=25.0, m2_axis_distance_mm=45.0),
    ...                          search=False)
    >>> blocked.ok, blocked.problems[-1]
    (False, 'M2 cuts through the M1 plate')
    """
    if margin_mm < 0:
        raise ValueError(f"margin_mm must be >= 0, got {margin_mm!r}")
    pixels = field_pixels(rig.camera)
    extents = footprint_extents(rig, pixels, margin_mm)
    designed = rig.with_extents(extents)
    planes = mirror_planes(designed)
    a = rig.camera.half_fov_rad[0]
    w = rig.mirrors.angle_rad
    reach = 0.5 * rig.mirrors.baseline_mm / math.sin(2 * w)
    ob = {"m1": rig.mirrors.m1_axis_distance_mm, "m2": rig.mirrors.m2_axis_distance_mm}
    ob["m4"], ob["m3"] = ob["m1"] + reach, ob["m2"] + reach
    specs = []
    for name in MIRROR_NAMES:
        p, e = planes[name], extents[name]
        (s0, s1), (t0, t1) = e.along_mm, e.height_mm
        centre = p.point + 0.5 * (s0 + s1) * p.s_axis + np.array([0.0, 0.5 * (t0 + t1), 0.0])
        eq6 = float(mirror_length_eq6(ob[name], a, w)) if w > a else float("nan")
        specs.append(MirrorSpec(name, e, tuple(map(float, p.point)), tuple(map(float, centre)),
                                tuple(map(float, p.normal)), float(ob[name]), eq6))
    obstructions = tuple(find_obstructions(designed, pixels))
    collisions = tuple(find_collisions(designed))
    shares = blocked_shares(designed) if obstructions or collisions else {view: 0.0 for view in VIEWS}
    wr = working_range(rig, near_mm, far_mm) if near_mm is not None and far_mm is not None else None
    window, suggestion, note = _search(rig, margin_mm, bool(obstructions or collisions)) if search else (None, None, "")
    return MirrorDesign(designed, tuple(specs), obstructions, collisions, wr, window, suggestion, note, shares)


def _search(rig: Rig, margin_mm: float, blocked: bool):
    """(the clear M2 range for the rig's c1, a clear (c1, c2) when the rig is blocked, why the search
    stopped short or ''), within one :class:`SearchBudget`."""
    budget = SearchBudget()
    window = suggestion = None
    try:
        window = clear_m2_window(rig, margin_mm, budget=budget)
        suggestion = suggest_layout(rig, margin_mm, budget=budget) if blocked else None
    except SearchLimit as exc:
        return window, None, str(exc)
    return window, suggestion, ""


#: The most trial layouts (c1, c2) one design's searches trace (:func:`clear_m2_window`, :func:`suggest_layout`):
#: a layout costs 3-10 ms, so a search answers in a few seconds whatever the rig; when it has spent them all
#: it stops and says so (:attr:`MirrorDesign.search_note`).
SEARCH_LAYOUTS = 1000
#: The most M2 positions one scan of c1 < c2 <= c1 + b tries: its step grows past ``step_mm`` on a wide rig.
SCAN_POSITIONS = 200
#: The most M1 positions :func:`suggest_layout` tries spread over its range before it bisects.
C1_PROBES = 6


class SearchLimit(Exception):
    """A search has traced :data:`SEARCH_LAYOUTS` layouts (raised by :class:`SearchBudget`)."""


class SearchBudget:
    """Counts the trial layouts a search traces; :meth:`spend` raises :class:`SearchLimit` past ``layouts``."""

    def __init__(self, layouts: int = SEARCH_LAYOUTS):
        self.layouts, self.spent = int(layouts), 0

    def spend(self) -> None:
        """Count one more trial layout; SearchLimit once the budget of :attr:`layouts` is spent."""
        if self.spent >= self.layouts:
            raise SearchLimit(f"the search for a clear layout stopped after {self.layouts} trial layouts (its limit)")
        self.spent += 1


def _clear(rig: Rig, c1: float, c2: float, margin_mm: float, pixels: np.ndarray,
           budget: SearchBudget | None = None) -> bool:
    if budget is not None:
        budget.spend()
    trial = rig.replace(m1_axis_distance_mm=c1, m2_axis_distance_mm=c2)
    trial = trial.with_extents(footprint_extents(trial, pixels, margin_mm))
    return not find_obstructions(trial, pixels) and not find_collisions(trial)


def clear_m2_window(rig: Rig, margin_mm: float = 0.0, step_mm: float = 0.5, tol_mm: float = 0.01,
                    budget: SearchBudget | None = None, positions: int = SCAN_POSITIONS) -> tuple[float, float] | None:
    """The range of c2 (M2's axis distance, mm) for which no path is blocked and no parts collide.

    Too close, M2 cuts into the plate or the right beam; too far, M2 grows into the left view's
    outgoing beam (for 45 deg mirrors and no plate: c2 < b (1 - tan a)^2 / (4 tan a)). Scans
    c1 < c2 <= c1 + b in ``step_mm`` steps (wider on a rig whose b needs more than ``positions`` of them)
    up to the end of the first clear run, then bisects both ends to ``tol_mm``. Returns None when no
    position is clear. ``budget`` counts the layouts traced (:class:`SearchBudget`).
    """
    pixels = field_pixels(rig.camera, per_side=33, interior=5)
    c1, b = rig.mirrors.m1_axis_distance_mm, rig.mirrors.baseline_mm
    step = max(step_mm, b / positions)

    def clear(c2):
        return _clear(rig, c1, c2, margin_mm, pixels, budget)

    grid = np.arange(c1 + step, c1 + b + 1e-9, step)
    first = last = None
    for k, c2 in enumerate(grid):
        if clear(c2):
            first = k if first is None else first
            last = k
        elif first is not None:
            break
    if first is None:
        return None

    def bisect(good, bad):
        while abs(good - bad) > tol_mm:
            mid = 0.5 * (good + bad)
            good, bad = (mid, bad) if clear(mid) else (good, mid)
        return good

    lo = bisect(grid[first], grid[first - 1] if first > 0 else c1 + 1e-6)
    hi = bisect(grid[last], grid[last + 1]) if last + 1 < len(grid) else grid[last]
    return float(lo), float(hi)


def suggest_layout(rig: Rig, margin_mm: float = 0.0, min_window_mm: float = 2.0, step_mm: float = 0.5,
                   budget: SearchBudget | None = None) -> tuple[float, float] | None:
    """A clear (c1, c2), mm: the largest M1 distance up to the rig's own, on a ``step_mm`` grid, whose M2
    window is at least ``min_window_mm`` wide, with M2 in the middle of that window. None when even
    c1 = 1 mm fails.

    The window narrows as M1 moves out (the plate nears M2), so the search tries :data:`C1_PROBES` M1
    positions spread from the rig's own down to 1 mm and bisects between the last that fails and the first
    that clears; each scan steps M2 by ``min_window_mm / 2`` (no wide enough window falls between two
    steps; wider steps on a wide rig: at most half of :data:`SCAN_POSITIONS`).
    ``budget`` counts the layouts traced (:class:`SearchBudget`).
    """
    c1_max = rig.mirrors.m1_axis_distance_mm
    if c1_max < 1.0:
        return None
    grid = c1_max - step_mm * np.arange(int((c1_max - 1.0) / step_mm) + 1)   # descending, down to >= 1 mm
    windows: dict[int, tuple[float, float] | None] = {}

    def wide(i: int) -> bool:
        if i not in windows:
            c1 = float(grid[i])
            trial = rig.replace(m1_axis_distance_mm=c1, m2_axis_distance_mm=c1 + rig.mirrors.baseline_mm)
            w = clear_m2_window(trial, margin_mm, step_mm=max(step_mm, min_window_mm / 2), budget=budget,
                                positions=SCAN_POSITIONS // 2)
            windows[i] = w if w is not None and w[1] - w[0] >= min_window_mm else None
        return windows[i] is not None

    stride = max(1, math.ceil((len(grid) - 1) / max(1, C1_PROBES - 1)))
    probes = sorted(set(range(0, len(grid), stride)) | {len(grid) - 1})
    bad, good = -1, None                        # the last probe that fails (none yet), the first that clears
    for i in probes:
        if wide(i):
            good = i
            break
        bad = i
    if good is None:
        return None
    while good - bad > 1:
        mid = (good + bad) // 2
        good, bad = (mid, bad) if wide(mid) else (good, mid)
    lo, hi = windows[good]
    return float(grid[good]), 0.5 * (lo + hi)
