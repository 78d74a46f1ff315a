"""Draw one build of a nominal rig within its tolerances (docs/tolerancing.md).

Sample ``index`` of a study seeded ``seed`` draws from ``np.random.SeedSequence([seed, index])``: its
children, one per parameter of :data:`psvs.study.tolerances.PARAMS` (in that order) and one more for the
card views' seed. A parameter's draw therefore depends on (seed, index, its name) only: not on the order the
samples run in, on the worker, nor on which other parameters the TOL file tolerances.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from psvs.optics.bounds import check_rig_bounds
from psvs.optics.rig import MIRROR_NAMES, MirrorError, Rig
from psvs.study.tolerances import PARAMS, Tolerances

_LENS = ("k1", "k2", "p1", "p2", "k3")
_BOX = ("box_x_deg", "box_y_deg", "box_z_deg")


def _seeds(seed: int, index: int) -> list:
    for name, v in (("seed", seed), ("index", index)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
            raise ValueError(f"{name} must be a whole number >= 0, got {v!r}")
    return np.random.SeedSequence([int(seed), int(index)]).spawn(len(PARAMS) + 1)


def draw_deviations(tol: Tolerances, seed: int, index: int) -> dict:
    """Every parameter's drawn deviation from nominal (key -> value in file units: degrees for ``_deg``
    keys, mm, px, or none); 0.0 for a parameter the TOL file does not tolerance."""
    children = _seeds(seed, index)
    out = {}
    for key, child in zip(PARAMS, children[:len(PARAMS)], strict=True):
        dist = tol.dists.get(key)
        v = 0.0 if dist is None else dist.draw(np.random.default_rng(child))
        out[key] = math.degrees(v) if key.endswith("_deg") else v
    return out


def views_seed(seed: int, index: int) -> int:
    """The card views' seed of sample ``index`` (a whole number >= 0: ``psvs card-views --seed``)."""
    return int(_seeds(seed, index)[-1].generate_state(1, dtype=np.uint32)[0] >> 1)


def apply_deviations(nominal: Rig, dev: dict) -> Rig:
    """``nominal`` with the deviations ``dev`` (key -> file units, :func:`draw_deviations`) added, and no
    calibration record; ValueError (one line) when the drawn build is not a rig (a plate under 0 mm, a
    split ratio outside 0..1, a tilt beyond the rig file's bounds)."""
    rad = {k: math.radians(v) if k.endswith("_deg") else v for k, v in dev.items()}
    errors = {}
    for name in MIRROR_NAMES:
        e = nominal.mirrors.error(name)
        errors[name] = MirrorError((e.tilt_rad[0] + rad.get(f"{name}_tilt_a_deg", 0.0),
                                    e.tilt_rad[1] + rad.get(f"{name}_tilt_b_deg", 0.0)),
                                   e.shift_mm + rad.get(f"{name}_shift_mm", 0.0))
    c, m = nominal.camera, nominal.mirrors
    try:
        rig = nominal.with_errors(errors).replace(
            box_rotation_rad=tuple(a + rad.get(k, 0.0) for a, k in zip(m.box_rotation_rad, _BOX, strict=True)),
            focal_length_mm=c.focal_length_mm + rad.get("focal_length_mm", 0.0),
            principal_point_px=(c.principal_point_px[0] + rad.get("cx_px", 0.0),
                                c.principal_point_px[1] + rad.get("cy_px", 0.0)),
            distortion=tuple(v + rad.get(k, 0.0) for v, k in zip(c.distortion, _LENS, strict=True)),
            plate_thickness_mm=m.plate_thickness_mm + rad.get("plate_thickness_mm", 0.0),
            refractive_index=m.refractive_index + rad.get("refractive_index", 0.0),
            split_ratio=m.split_ratio + rad.get("split_ratio", 0.0))
        check_rig_bounds(rig, memory=False)
    except ValueError as exc:
        raise ValueError(f"the drawn build is no rig: {exc}") from None
    return dataclasses.replace(rig, calibration=None)


#: How far out a tolerance's draws are checked before a study (:func:`check_tolerance_edges`): a uniform's
#: half-width, a normal's 2 sigma (one draw in 22 goes further).
NORMAL_EDGE_SIGMA = 2.0


def check_tolerance_edges(nominal: Rig, tol: Tolerances) -> None:
    """ValueError, before any sample, naming a tolerance whose draws are no rig even alone (each key at +- a
    uniform's half-width or a normal's :data:`NORMAL_EDGE_SIGMA` sigma, the others nominal): a study of such
    builds scores nothing (a tilt of 20 deg beyond the rig file's bounds failed every sample)."""
    for key, dist in tol.dists.items():
        width = math.degrees(dist.width) if key.endswith("_deg") else dist.width      # file units
        edge = width * (1.0 if dist.kind == "uniform" else NORMAL_EDGE_SIGMA)
        what = "half-width" if dist.kind == "uniform" else f"{NORMAL_EDGE_SIGMA:g} sigma"
        for value in (edge, -edge):
            try:
                apply_deviations(nominal, {key: value})
            except ValueError as exc:
                raise ValueError(f"tolerances: {key} {{ {dist.kind} = {width:g} }}: a build at its {what} "
                                 f"({value:+g}) is no rig ({str(exc).removeprefix('the drawn build is no rig: ')}); "
                                 "a tolerance must draw builds of the rig") from None


def draw_build(nominal: Rig, tol: Tolerances, seed: int, index: int) -> tuple[Rig, dict]:
    """Build ``index`` of a study seeded ``seed``: the rig as built and its drawn deviations (file units,
    :func:`draw_deviations`).

    Examples
    --------
    >>> from psvs.io.params import load_rig
    >>> from psvs.study.tolerances import tolerances_from_dict
    >>> tol = tolerances_from_dict({"tolerances": {"mirror_tilt_deg": {"uniform": 0.2}}})
    >>> rig, dev = draw_build(load_rig("default"), tol, seed=1, index=0)
    >>> abs(dev["m1_tilt_b_deg"]) <= 0.2, dev["m1_shift_mm"], dev == draw_build(load_rig("default"), tol, 1, 0)[1]
    (True, 0.0, True)
    >>> bool(np.isclose(np.degrees(rig.mirrors.m1_error.tilt_rad[1]), dev["m1_tilt_b_deg"]))
    True
    """
    dev = draw_deviations(tol, seed, index)
    return apply_deviations(nominal, dev), dev
