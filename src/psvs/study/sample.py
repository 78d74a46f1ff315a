"""One sample of a Monte-Carlo study: draw a build, render its card views, calibrate it from the nominal design
exactly as ``psvs calibrate`` does, and score it (docs/tolerancing.md).

- The card views are what ``psvs card-views DIR --rig BUILD --views N --seed S`` writes (the same poses,
  renders and files, :func:`render_card_folder`), in a temporary folder; the calibration is
  :func:`psvs.calibrate.folder.calibrate_folder` on that folder from the nominal rig, the function
  ``psvs calibrate`` calls. A sample thus gives exactly what that build calibrated alone gives.
- The test set: scene points on a pixel lattice of the nominal left view at several depths over the working
  range (:func:`psvs.measure.tolerance.field_points`), projected through the *build* (exact optics: true
  correspondences, no detection) and triangulated with the calibrated rig (exact model). No image can fix
  where frame C sits behind the mirrors (docs/calibration.md, "What a card cannot see"): the 3-D error is
  taken after the best rigid motion (Kabsch); the error in frame C itself is reported beside it.
- Table I (optional, ``[test] table1``: 15 more renders): the paper's test distances measured with the
  calibrated rig (:func:`psvs.accuracy.pattern_measure.measure_pattern`), the depth error after the common offset
  (the robot's unknown zero) and the first-to-last distance error.
- The twins' row offset before calibration: :func:`psvs.mount.guide.row_offsets_px` over the working range,
  the largest (px).

:func:`run_sample` returns one flat row (scalars only, the same keys for every sample, :data:`COLUMNS`).
"""
from __future__ import annotations

import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from psvs.calibrate.folder import calibrate_folder
from psvs.errors import MeasurementError
from psvs.measure.tolerance import field_points
from psvs.measure.triangulate import triangulate
from psvs.mount.guide import designed_twin, row_offsets_px, working_points
from psvs.optics.project import in_image, project_points
from psvs.optics.rig import Rig
from psvs.study.build import apply_deviations, check_tolerance_edges, draw_deviations, views_seed
from psvs.study.tolerances import PARAMS, Procedure, TestSet, Tolerances

#: The scores of a row, each in its unit (NaN when not measured).
SCORES = ("rms_3d_mm", "max_3d_mm", "raw_rms_3d_mm", "reproj_rms_px", "row_offset_px", "table1_z_rms_mm",
          "table1_z_max_mm", "table1_a_mm")
#: Columns that time the sample (the only ones that differ between two runs of one sample).
TIMING = ("cpu_s", "wall_s")
#: Every column of a row, in order; the drawn deviations are ``dev_<key>`` in file units.
COLUMNS = ("index", "seed", "views_seed", "ok", "reason", *SCORES, "images_used", "images_skipped", "test_points",
           "table1_note", *TIMING, *(f"dev_{k}" for k in PARAMS))


def render_card_folder(build: Rig, procedure: Procedure, seed: int, folder) -> None:
    """What ``psvs card-views FOLDER --rig BUILD --views N --seed SEED [--interleave]`` writes
    (``card_NN.png`` and ``target.toml``), with the procedure's depths, tilt, supersampling and sensor."""
    from psvs.calibrate.synthetic import check_card_fits, random_poses, render_grid_shots
    from psvs.io.atomic import write_atomic
    from psvs.io.images import write_png
    from psvs.simulate.sensor import Sensor
    from psvs.targets.target_file import dumps_target
    p, folder = procedure, Path(folder)
    z_range = (p.near_mm, p.far_mm)
    check_card_fits(build, p.card, p.views, z_range, tilt_deg=p.tilt_deg, apart=not p.interleave)
    poses = random_poses(build, p.card, p.views, seed=seed, z_range_mm=z_range, tilt_deg=p.tilt_deg,
                         apart=not p.interleave)
    sensor = Sensor(blur_sigma_px=p.blur_px, read_noise_e=p.read_noise_e)
    shots = render_grid_shots(build, p.card, poses, seed=seed, supersample=p.supersample, sensor=sensor)
    for k, shot in enumerate(shots):
        write_png(folder / f"card_{k:02d}.png", shot.image)
    write_atomic(folder / "target.toml", dumps_target(p.card))


def render_sweep_folder(build: Rig, procedure: Procedure, seed: int, folder) -> None:
    """What ``psvs sweep-views FOLDER --rig BUILD --from-mm A --to-mm B --step-mm S --seed SEED`` writes
    (``sweep_NNNN_N.png`` and ``sweep.csv``: the Fig. 9 pattern on the robot's holder at each depth)."""
    from psvs.accuracy.table1 import ROBOT_OFFSET_MM, check_pattern_depths, pattern_image
    from psvs.calibrate.sweep import dumps_sweep
    from psvs.io.atomic import write_atomic
    from psvs.io.images import write_png
    lo, hi, step = procedure.sweep_mm
    depths = np.arange(lo, hi + 1e-9, step)
    check_pattern_depths(build, float(depths[0]), float(depths[-1]), "the sweep's depths")
    rows = []
    for k, z in enumerate(depths):
        name = f"sweep_{z:06.1f}.png".replace(".", "_", 1)
        write_png(Path(folder) / name, pattern_image(build, float(z), seed + k))
        rows.append((name, float(z) - ROBOT_OFFSET_MM))
    write_atomic(Path(folder) / "sweep.csv", dumps_sweep(rows))


def scoring_points_mm(nominal: Rig, test: TestSet) -> np.ndarray:
    """(N, 3) mm: the test set's scene points (a ``grid`` x ``grid`` lattice of the nominal design's left
    view at ``depths`` depths over the working range, seen by both of its views)."""
    return field_points(designed_twin(nominal), test.near_mm, test.far_mm, n_u=test.grid, n_v=test.grid,
                        n_z=test.depths)


def reconstruction_errors(calibrated: Rig, build: Rig, points_mm: np.ndarray) -> dict:
    """3-D errors (mm) of ``points_mm`` (N, 3) seen through ``build`` and triangulated with ``calibrated``
    (exact model): RMS and max after the best rigid motion, RMS in frame C, and how many points were used;
    MeasurementError when fewer than 3 points are seen by both views of the build and triangulated."""
    uv_l, ok_l = project_points(points_mm, build, "left")
    uv_r, ok_r = project_points(points_mm, build, "right")
    seen = ok_l & ok_r & in_image(uv_l, build) & in_image(uv_r, build)
    tri = triangulate(uv_l[seen], uv_r[seen], calibrated, model="exact")
    got, truth = tri.points_mm[tri.valid], points_mm[seen][tri.valid]
    if len(got) < 3:
        raise MeasurementError(f"only {len(got)} of the {len(points_mm)} test points are seen by both views of "
                               "the build and triangulated by the calibrated rig")
    raw = np.linalg.norm(got - truth, axis=1)
    c_got, c_truth = got.mean(axis=0), truth.mean(axis=0)
    turn, _ = Rotation.align_vectors(truth - c_truth, got - c_got)
    aligned = np.linalg.norm(turn.apply(got - c_got) + c_truth - truth, axis=1)
    return {"rms_3d_mm": float(np.sqrt(np.mean(aligned ** 2))), "max_3d_mm": float(aligned.max()),
            "raw_rms_3d_mm": float(np.sqrt(np.mean(raw ** 2))), "test_points": int(len(got))}


def table1_errors(calibrated: Rig, build: Rig) -> dict:
    """The paper's Table I on ``build`` measured with ``calibrated``: RMS and max |Z error| after the common
    offset (mm) and the mean |first-to-last distance - 80 mm| (mm). ValueError/MeasurementError when the
    pattern is not found or measured at some distance."""
    from psvs.accuracy.pattern_measure import measure_pattern
    from psvs.accuracy.table1 import PAPER_TABLE1, check_pattern_depths, pattern_image
    z_true = PAPER_TABLE1[:, 0]
    check_pattern_depths(build, float(z_true.min()), float(z_true.max()), "Table I's depths")
    meas = [measure_pattern(pattern_image(build, float(z), int(z) + 1), calibrated) for z in z_true]
    dz = np.array([m.Z_mm for m in meas]) - z_true
    dz -= dz.mean()
    a = np.array([m.first_last_distance_mm for m in meas])
    return {"table1_z_rms_mm": float(np.sqrt(np.mean(dz ** 2))), "table1_z_max_mm": float(np.abs(dz).max()),
            "table1_a_mm": float(np.mean(np.abs(a - 80.0)))}


def row_offset_max_px(build: Rig, test: TestSet) -> float:
    """The largest twins' row offset (px) of the build before calibration over the test's working range
    (:func:`psvs.mount.guide.row_offsets_px`)."""
    r = row_offsets_px(build, working_points(build, test.near_mm, test.far_mm))
    r = r[np.isfinite(r)]
    return float(np.abs(r).max()) if len(r) else math.nan


def check_study(nominal: Rig, tol: Tolerances) -> float:
    """ValueError, before any sample, when the nominal design cannot run the study's procedure at all: a card
    no pose of the nominal rig could show (:func:`psvs.calibrate.synthetic.check_card_fits`), a sweep or Table
    I at depths where the rig does not show the Fig. 9 pattern, a test range both views hardly share, or one
    sample's renders beyond the memory or the time limit (:func:`psvs.simulate.render.check_render_work`).
    A tolerance whose draws are no rig even alone is refused too (:func:`psvs.study.build.check_tolerance_edges`).
    A build that departs from the design may still fail: that is a scored failure, not this error. Returns
    the estimated time (s) of one sample's renders (:func:`psvs.simulate.render.render_seconds`)."""
    from psvs.accuracy.table1 import PAPER_TABLE1, SUPERSAMPLE, check_pattern_depths
    from psvs.calibrate.synthetic import check_card_fits
    from psvs.simulate.render import check_render_work, render_seconds
    check_tolerance_edges(nominal, tol)
    p, test = tol.procedure, tol.test
    if p.method == "sweep":
        lo, hi, step = p.sweep_mm
        last = float(np.arange(lo, hi + 1e-9, step)[-1])
        check_pattern_depths(nominal, lo, last, "calibration.sweep's depths")
        count = math.ceil((hi + 1e-9 - lo) / step)
        check_render_work(nominal, SUPERSAMPLE, count, "calibration.sweep")
        seconds = render_seconds(nominal, SUPERSAMPLE, count)
    else:
        try:
            check_card_fits(nominal, p.card, p.views, (p.near_mm, p.far_mm), tilt_deg=p.tilt_deg,
                            apart=not p.interleave)
        except ValueError as exc:
            raise ValueError(f"calibration.card: {exc}") from None
        check_render_work(nominal, p.supersample, p.views, f"calibration.views = {p.views}")
        seconds = render_seconds(nominal, p.supersample, p.views)
    if test.table1:
        z = PAPER_TABLE1[:, 0]
        check_pattern_depths(nominal, float(z.min()), float(z.max()), "test.table1: Table I's depths")
        check_render_work(nominal, SUPERSAMPLE, len(z), "test.table1")
        seconds += render_seconds(nominal, SUPERSAMPLE, len(z))
    if len(scoring_points_mm(nominal, test)) < 3:
        raise ValueError(f"test: the nominal rig's views share fewer than 3 test points over "
                         f"{test.near_mm:g}-{test.far_mm:g} mm")
    return seconds


def _empty_row(seed: int, index: int, dev: dict) -> dict:
    row = {c: math.nan for c in COLUMNS}
    row.update(index=int(index), seed=int(seed), views_seed=views_seed(seed, index), ok=False, reason="",
               images_used=0, images_skipped=0, test_points=0, table1_note="")
    row.update({f"dev_{k}": float(v) for k, v in dev.items()})
    return row


#: The folder (set by ``psvs montecarlo`` before its local workers start, so they inherit it) that holds the
#: samples' render folders; the command removes it at its end, whatever ends it (a worker killed with the
#: cluster leaves nothing in TMPDIR).
STUDY_TMP_ENV = "PSVS_STUDY_TMP"


def _calibrate_and_score(row: dict, nominal: Rig, build: Rig, tol: Tolerances) -> None:
    """Render, calibrate and score into ``row``; ValueError/MeasurementError when calibration fails."""
    parent = os.environ.get(STUDY_TMP_ENV)
    with tempfile.TemporaryDirectory(prefix="psvs-study-", dir=parent if parent and os.path.isdir(parent) else None
                                     ) as tmp:
        render = render_sweep_folder if tol.procedure.method == "sweep" else render_card_folder
        render(build, tol.procedure, row["views_seed"], tmp)
        try:
            res = calibrate_folder(tmp, nominal)
        except (ValueError, MeasurementError) as exc:    # the reason names no temporary folder: a rerun's row
            raise type(exc)(str(exc).replace(tmp, "the sample's views")) from None   # is the same row
    b = res.bundle
    row.update(images_used=len(res.used), images_skipped=len(res.skipped), reproj_rms_px=float(b.rms_px))
    row.update(reconstruction_errors(res.rig, build, scoring_points_mm(nominal, tol.test)))
    row["ok"] = bool(b.success)
    row["reason"] = "" if b.success else f"solver: {b.message}"
    if tol.test.table1:
        try:
            row.update(table1_errors(res.rig, build))
        except (ValueError, MeasurementError) as exc:
            row["table1_note"] = str(exc).splitlines()[0] if str(exc) else type(exc).__name__


def run_sample(nominal: Rig, tol: Tolerances, seed: int, index: int) -> dict:
    """Sample ``index`` of a study seeded ``seed``: one flat row (:data:`COLUMNS`). A build that is no rig,
    or whose calibration fails (``ValueError``/``MeasurementError``: too few usable views, a card no pose
    shows), is a row with ``ok`` False and the message in ``reason``; its deviations and its row offset
    before calibration are still there."""
    t_cpu, t_wall = time.process_time(), time.perf_counter()
    dev = draw_deviations(tol, seed, index)
    row = _empty_row(seed, index, dev)
    try:
        build = apply_deviations(nominal, dev)
        row["row_offset_px"] = row_offset_max_px(build, tol.test)
        _calibrate_and_score(row, nominal, build, tol)
    except (ValueError, MeasurementError) as exc:
        row["ok"], row["reason"] = False, str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    row["cpu_s"], row["wall_s"] = time.process_time() - t_cpu, time.perf_counter() - t_wall
    return row
