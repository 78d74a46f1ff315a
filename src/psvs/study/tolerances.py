"""TOL.toml: the tolerances of a build and the calibration a Monte-Carlo study simulates (docs/tolerancing.md).

Three tables, every one optional, every key optional; an unknown key, a bad value or a wrong type is a
one-line ``ValueError`` naming the key::

    [tolerances]                       # each: { uniform = HALF_WIDTH } or { normal = SIGMA }, file units
    mirror_tilt_deg = { uniform = 0.2 }   # both tilts of every mirror (a per-mirror key overrides it)
    mirror_shift_mm = { uniform = 0.5 }   # every mirror along its normal
    m3_tilt_b_deg = { normal = 0.05 }     # one parameter: m1..m4 _tilt_a_deg, _tilt_b_deg, _shift_mm
    box_rotation_deg = { uniform = 0.1 }  # the mirror box turned on the camera (box_x_deg, box_y_deg, box_z_deg)
    focal_length_mm = { normal = 0.05 }
    principal_point_px = { normal = 5 }   # cx_px and cy_px
    k1 = { normal = 0.01 }                # OpenCV's k1 k2 p1 p2 k3
    plate_thickness_mm = { uniform = 0.05 }
    refractive_index = { uniform = 0.002 }
    split_ratio = { uniform = 0.05 }

    [calibration]                      # the card views a user takes (psvs card-views' defaults)
    views = 16  near_mm = 450  far_mm = 1000  tilt_deg = 25
    card = { rows = 4, cols = 6, spacing_mm = 14, diameter_mm = 7 }
    supersample = 2  read_noise_e = 15  blur_px = 0.6  interleave = false
    method = "card"                    # or "sweep": the paper's robot sweep (psvs sweep-views) instead
    sweep = { from_mm = 425, to_mm = 1175, step_mm = 50 }

    [test]                             # how each calibrated build is scored
    near_mm = 400  far_mm = 1200  depths = 5  grid = 9  table1 = false

    [targets]                          # what a build must meet (the report's fractions)
    rms_3d_mm = 0.5  ...

Every drawn value is a deviation added to the nominal rig's value; angles are degrees in the file and
radians in the :class:`Tolerances`' parameters (``_rad``). Detection noise is not a number here: it comes
from the image, the renderer's sensor (shot noise, ``read_noise_e``, the lens blur ``blur_px``), so the
detector ``psvs calibrate`` runs sees what it would see on a real camera.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

from psvs.io.schema import Field, check_keys, read_fields
from psvs.io.tomlfile import load_toml
from psvs.simulate.sensor import MAX_BLUR_PX
from psvs.simulate.textures import CircleGrid

#: Every parameter a build may be toleranced in, in draw order: (file key, unit in code).
PARAMS = (*(f"m{k}_{p}" for k in range(1, 5) for p in ("tilt_a_deg", "tilt_b_deg", "shift_mm")),
          "box_x_deg", "box_y_deg", "box_z_deg", "focal_length_mm", "cx_px", "cy_px", "k1", "k2", "p1", "p2", "k3",
          "plate_thickness_mm", "refractive_index", "split_ratio")
#: Keys that set a group of parameters (an individual key in the same file overrides its group's).
GROUPS = {"mirror_tilt_deg": tuple(f"m{k}_tilt_{a}_deg" for k in range(1, 5) for a in "ab"),
          "mirror_shift_mm": tuple(f"m{k}_shift_mm" for k in range(1, 5)),
          "box_rotation_deg": ("box_x_deg", "box_y_deg", "box_z_deg"),
          "principal_point_px": ("cx_px", "cy_px")}
#: Score names a [targets] table may hold (psvs.study.sample's columns), each met when the score is <= it.
TARGET_KEYS = ("rms_3d_mm", "max_3d_mm", "raw_rms_3d_mm", "reproj_rms_px", "row_offset_px", "table1_z_rms_mm",
               "table1_z_max_mm", "table1_a_mm")
_KINDS = ("uniform", "normal")


@dataclass(frozen=True)
class Dist:
    """A parameter's distribution about its nominal value: ``uniform`` over +-``width`` or ``normal`` with
    sigma ``width`` (code units: rad for angles)."""

    kind: str
    width: float

    def draw(self, rng) -> float:
        """One deviation from ``rng`` (a numpy Generator; one variate whatever the kind)."""
        if self.kind == "uniform":
            return float((2.0 * rng.random() - 1.0) * self.width)
        return float(rng.standard_normal() * self.width)


@dataclass(frozen=True)
class Procedure:
    """The calibration simulated per build: ``views`` card views (``card``) at ``near_mm``..``far_mm``,
    tilted up to ``tilt_deg`` (psvs card-views' poses), rendered at ``supersample`` with the sensor's
    ``read_noise_e`` (electrons) and lens blur ``blur_px`` (sigma, px); with ``interleave`` the card's two
    copies may interleave (``psvs card-views --interleave``: a card wider than its disparity). With
    ``method`` "sweep", the paper's robot sweep instead (``psvs sweep-views``: the Fig. 9 pattern from
    ``sweep_mm`` = (from, to, step) mm, rendered as that command does; the card keys do not apply)."""

    views: int = 16
    near_mm: float = 450.0
    far_mm: float = 1000.0
    tilt_deg: float = 25.0
    card: CircleGrid = field(default_factory=lambda: CircleGrid(4, 6, 14.0, 7.0))
    supersample: int = 2
    read_noise_e: float = 15.0
    blur_px: float = 0.6
    interleave: bool = False
    method: str = "card"
    sweep_mm: tuple = (425.0, 1175.0, 50.0)


@dataclass(frozen=True)
class TestSet:
    """How a calibrated build is scored: points on a ``grid`` x ``grid`` pixel lattice of the left view at
    ``depths`` depths over ``near_mm``..``far_mm``; with ``table1``, the paper's Table I too (15 renders)."""

    near_mm: float = 400.0
    far_mm: float = 1200.0
    depths: int = 5
    grid: int = 9
    table1: bool = False

    __test__ = False     # not a pytest class


@dataclass(frozen=True)
class Tolerances:
    """A TOL.toml: ``dists`` (parameter key -> :class:`Dist`, code units), the calibration ``procedure``,
    the ``test`` set and the ``targets`` (score -> largest value that meets it)."""

    dists: dict = field(default_factory=dict)
    procedure: Procedure = field(default_factory=Procedure)
    test: TestSet = field(default_factory=TestSet)
    targets: dict = field(default_factory=dict)


_POSITIVE = Field("number", low=0.0, low_open=True)
_AT_LEAST_0 = Field("number", low=0.0)
#: The tables' schemas (:mod:`psvs.io.schema`); defaults are Procedure's and TestSet's.
CARD = {"rows": Field("integer", 2, 50), "cols": Field("integer", 2, 50), "spacing_mm": _POSITIVE,
        "diameter_mm": _POSITIVE}
PROCEDURE = {"views": Field("integer", 3, 60), "near_mm": _POSITIVE, "far_mm": _POSITIVE,
             "tilt_deg": Field("number", 0.0, 60.0, note="a card seen more obliquely is not read"),
             "card": Field("table"), "supersample": Field("integer", 1, 4), "read_noise_e": _AT_LEAST_0,
             "blur_px": Field("number", 0.0, MAX_BLUR_PX), "interleave": Field("flag"),
             "method": Field("string", choices=("card", "sweep")), "sweep": Field("table")}
SWEEP = {"from_mm": _POSITIVE, "to_mm": _POSITIVE, "step_mm": _POSITIVE}
TEST = {"near_mm": _POSITIVE, "far_mm": _POSITIVE, "depths": Field("integer", 1, 50), "grid": Field("integer", 2, 50),
        "table1": Field("flag")}


def _dist(value, key: str) -> Dist:
    where = f"tolerances.{key}"
    if not isinstance(value, dict) or len(value) != 1 or next(iter(value)) not in _KINDS:
        raise ValueError(f"{where} must be {{ uniform = HALF_WIDTH }} or {{ normal = SIGMA }}, got {value!r}")
    (kind, width), = value.items()
    width = _AT_LEAST_0.value(width, f"{where}.{kind}")
    return Dist(kind, math.radians(width) if key.endswith("_deg") else width)


def _dists(table: dict) -> dict:
    out = {}
    for group, members in GROUPS.items():
        if group in table:
            d = _dist(table[group], group)
            out.update({m: d for m in members})
    out.update({k: _dist(v, k) for k, v in table.items() if k in PARAMS})
    return {k: out[k] for k in PARAMS if k in out}


def _card(value) -> CircleGrid:
    d = CircleGrid(4, 6, 14.0, 7.0)
    t = {k: getattr(d, k) for k in CARD} | read_fields(value, "calibration.card", CARD)
    try:
        return CircleGrid(**t)
    except ValueError as exc:
        raise ValueError(f"calibration.card: {exc}") from None


def _procedure(table: dict) -> Procedure:
    d = Procedure()
    t = read_fields(table, "calibration", PROCEDURE)
    v = {k: t.get(k, getattr(d, k)) for k in ("views", "near_mm", "far_mm", "tilt_deg", "supersample",
                                              "read_noise_e", "blur_px", "interleave", "method")}
    if v["far_mm"] <= v["near_mm"]:
        raise ValueError(f"calibration.far_mm must be > calibration.near_mm ({v['near_mm']:g}), got {v['far_mm']:g}")
    card = _card(t["card"]) if "card" in t else d.card
    return Procedure(card=card, sweep_mm=_sweep(t.get("sweep", {})), **v)


def _sweep(value) -> tuple:
    d = dict(zip(SWEEP, Procedure().sweep_mm, strict=True))
    t = d | read_fields(value, "calibration.sweep", SWEEP)
    lo, hi, step = (t[k] for k in SWEEP)
    if hi < lo:
        raise ValueError(f"calibration.sweep.to_mm must be >= calibration.sweep.from_mm ({lo:g}), got {hi:g}")
    n = math.ceil((hi + 1e-9 - lo) / step)
    if not 3 <= n <= 60:
        raise ValueError(f"calibration.sweep has {n} positions; give 3-60 (from_mm, to_mm, step_mm)")
    return lo, hi, step


def _test(table: dict) -> TestSet:
    d = TestSet()
    t = {k: getattr(d, k) for k in TEST} | read_fields(table, "test", TEST)
    if t["far_mm"] <= t["near_mm"]:
        raise ValueError(f"test.far_mm must be > test.near_mm ({t['near_mm']:g}), got {t['far_mm']:g}")
    return TestSet(**t)


def tolerances_from_dict(data: dict) -> Tolerances:
    """A :class:`Tolerances` from a parsed TOL file; ValueError naming the first bad key."""
    unknown = sorted(set(data) - {"tolerances", "calibration", "test", "targets"})
    if unknown:
        raise ValueError(f"unknown table [{unknown[0]}] (allowed: [tolerances], [calibration], [test], [targets])")
    dists = _dists(check_keys(data.get("tolerances", {}), "tolerances", optional=(*GROUPS, *PARAMS)))
    procedure = _procedure(data.get("calibration", {}))
    test = _test(data.get("test", {}))
    targets = read_fields(data.get("targets", {}), "targets", dict.fromkeys(TARGET_KEYS, _POSITIVE))
    return Tolerances(dists, procedure, test, targets)


#: The shipped example (psvs/rigs/tolerances_default.toml): the default rig's mirrors to +-0.2 deg, +-0.5 mm.
SHIPPED_TOLERANCES = {"default": "tolerances_default.toml"}


def tolerances_path(path) -> Path:
    """The file a TOL argument names: the path itself, or a shipped name (``default``) when no such file
    exists."""
    p = Path(path)
    if not p.exists() and str(p) in SHIPPED_TOLERANCES:
        return Path(str(resources.files("psvs.rigs").joinpath(SHIPPED_TOLERANCES[str(p)])))
    return p


def load_tolerances(path) -> Tolerances:
    """Read a TOL.toml (:func:`tolerances_from_dict`), or the shipped one by its name (``default``);
    errors name the file and the key."""
    path = tolerances_path(path)
    data = load_toml(path, "tolerances")
    try:
        return tolerances_from_dict(data)
    except (ValueError, TypeError) as exc:
        raise type(exc)(f"{path}: {exc}") from None
