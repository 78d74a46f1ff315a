"""The paper's accuracy experiment (section IV.2, Table I, Fig. 10), reproduced in simulation.

A robot holds the circle pattern (slightly turned and off-centre on its holder) and moves it along Z.
The rig is calibrated either from a calibration sweep at 16 distances (425-1175 mm every 50 mm, not the test
distances; the paper's method) or from 18 views of a hand-held 4x6 circle-grid card (:data:`CARD`), starting
from a rough guess (f +10 %, b +10 mm, principal point off, plate 2 mm, no lens distortion, no mirror
error) or from a given nominal design; the paper's 15 test distances are then measured with the calibrated
rig: depth Z, circle diameter (10 mm) and first-last centre distance (80 mm). Everything is rendered through
the *true* rig, which may be a misaligned build (examples/rigs/misaligned.toml).
"""
from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from psvs.accuracy.pattern_measure import PatternMeasurement, measure_pattern, without_range_hint
from psvs.calibrate.bundle import BundleResult, bundle_adjust
from psvs.calibrate.sweep import calibrate_sweep
from psvs.errors import MeasurementError
from psvs.io.atomic import write_atomic
from psvs.optics.rig import MIRROR_NAMES, MirrorError, Rig
from psvs.simulate.builtin import builtin_scene
from psvs.simulate.render import render
from psvs.simulate.textures import CircleGrid, Circles
from psvs.targets.discs import MIN_AREA_PX
from psvs.targets.pattern import detect_with_start

#: Table I of the paper: Z meas., Z calc., d calc., a calc. (mm); d meas. = 10, a meas. = 80.
PAPER_TABLE1 = np.array([
    [440.0, 439.082, 10.043, 78.541], [489.0, 490.747, 10.174, 78.399], [537.5, 539.249, 10.136, 78.030],
    [590.0, 587.431, 10.187, 79.198], [636.0, 634.599, 10.288, 78.956], [685.5, 684.006, 9.933, 79.423],
    [736.0, 728.767, 9.984, 79.824], [786.0, 777.394, 9.942, 79.362], [833.0, 830.534, 9.888, 79.194],
    [883.5, 880.250, 9.725, 80.110], [928.5, 929.444, 10.230, 79.872], [977.5, 975.734, 9.950, 80.117],
    [1027.0, 1025.416, 9.821, 80.120], [1073.0, 1071.799, 10.078, 80.127], [1123.0, 1122.425, 9.721, 81.178]])
SWEEP_Z_MM = np.arange(425.0, 1176.0, 50.0)   # 16 positions, none at a test distance
HOLDER = dict(tilt_x_deg=2.0, tilt_y_deg=-3.0, x_mm=6.0, y_mm=-4.0)   # the pattern on the robot
ROBOT_OFFSET_MM = -312.7                                              # robot reading = Z - offset
CARD = CircleGrid(4, 6, 14.0, 7.0)                                    # the hand-held card (docs/calibration.md)
CARD_VIEWS = 18
PATTERN = Circles()                                                   # Fig. 9's row of circles (builtin fig9)
SUPERSAMPLE = 2                                                       # of every render (render's default)


def pattern_depths_mm(rig: Rig, margin_px: float = 12.0) -> tuple[float, float]:
    """The depths (mm) at which :func:`pattern_image` shows the pattern so that
    it can be found through ``rig``: both copies of its row of circles ``margin_px`` inside the image, each
    circle at least :data:`~psvs.targets.discs.MIN_AREA_PX` in area (each view the rig's pinhole at its
    virtual centre; lenient: the holder's small turn and offset are left out; the detector's largest disc
    comes from the rig and the depths, :func:`psvs.targets.pattern.disc_size_range_px`). Empty (lo > hi)
    when no depth is.
    ValueError when the pattern is wider than the baseline: its two copies then overlap at every depth."""
    cam, b, zv = rig.camera, rig.mirrors.baseline_mm, rig.virtual_z_mm
    (w, _), px, f = cam.image_size_px, cam.pixel_pitch_mm[0], cam.focal_length_mm
    d, width = PATTERN.diameter_mm, (PATTERN.count - 1) * PATTERN.spacing_mm + PATTERN.diameter_mm
    if width >= b:
        raise ValueError(f"the Fig. 9 pattern ({width:g} mm wide) is wider than this rig's baseline ({b:g} mm): "
                         f"its two copies overlap at every depth")
    smallest = 2 * np.sqrt(MIN_AREA_PX / np.pi)
    lo = zv + (width + b) * f / (px * max(w - 1 - 2 * margin_px, 1e-9))
    return float(lo), float(zv + d * f / (smallest * px))


def check_pattern_depths(rig: Rig, near_mm: float, far_mm: float, what: str) -> None:
    """ValueError naming ``what`` (the depths the user asked for) unless ``near_mm``..``far_mm`` lie within
    :func:`pattern_depths_mm`: the pattern would not be found in some image."""
    lo, hi = pattern_depths_mm(rig)
    if not lo <= near_mm <= far_mm <= hi:
        where = f"lie outside {lo:.0f}-{hi:.0f} mm, where" if lo <= hi else "are no use: at no depth"
        raise ValueError(f"{what} {near_mm:g}-{far_mm:g} mm {where} this rig shows the Fig. 9 pattern so that it "
                         f"is found (both copies of its row of circles in the image, each circle at least "
                         f"{2 * np.sqrt(MIN_AREA_PX / np.pi):.1f} px across)")


@dataclass(frozen=True, eq=False)
class Table1:
    """Table I reproduced: the ``calibration`` the sweep gave, the true depths ``z_true_mm`` (15,) and the
    pattern's measurement at each (:func:`psvs.accuracy.pattern_measure.measure_pattern`)."""

    calibration: BundleResult
    z_true_mm: np.ndarray
    measurements: list[PatternMeasurement]

    def rows(self) -> np.ndarray:
        """(15, 4): Z meas., Z calc., d calc., a calc. (mm), ours."""
        return np.array([[z, m.Z_mm, m.diameter_mm, m.first_last_distance_mm]
                         for z, m in zip(self.z_true_mm, self.measurements, strict=True)])

    def summary(self) -> dict:
        """psvs's and the paper's errors side by side (``ours``, ``paper``): mean and largest |Z error|, diameter and
        first-last distance errors against the pattern's 10 mm and 80 mm (mm)."""
        r = self.rows()
        p = PAPER_TABLE1
        ze, de, ae = np.abs(r[:, 1] - r[:, 0]), np.abs(r[:, 2] - 10.0), np.abs(r[:, 3] - 80.0)
        pz, pd, pa = np.abs(p[:, 1] - p[:, 0]), np.abs(p[:, 2] - 10.0), np.abs(p[:, 3] - 80.0)
        return {"ours": {"mean_abs_z_error_mm": ze.mean(), "max_abs_z_error_mm": ze.max(),
                         "mean_diameter_error_mm": de.mean(), "mean_distance_error_mm": ae.mean()},
                "paper": {"mean_abs_z_error_mm": pz.mean(), "max_abs_z_error_mm": pz.max(),
                          "mean_diameter_error_mm": pd.mean(), "mean_distance_error_mm": pa.mean()}}


def pattern_image(rig: Rig, z: float, seed: int) -> np.ndarray:
    """The Fig. 9 pattern on the robot's holder (:data:`HOLDER`) at depth ``z`` mm, rendered through ``rig``
    (adaptively: the sheet is smooth but for its circles, 9 px and more, and its border)."""
    spec = ",".join(f"{k}={v}" for k, v in HOLDER.items())
    return render(builtin_scene(f"fig9:distance_mm={z},{spec}"), rig, seed=seed, supersample=SUPERSAMPLE,
                  adaptive=True).image


def rough_start(rig: Rig) -> Rig:
    """The rig as a user would guess it: f 10 % long, b 10 mm long, principal point off, plate 2 mm, and
    the design's perfect mirrors and distortion-free lens."""
    c = rig.camera
    rough = rig.replace(focal_length_mm=1.1 * c.focal_length_mm, baseline_mm=rig.mirrors.baseline_mm + 10.0,
                        principal_point_px=(c.principal_point_px[0] + 3.0, c.principal_point_px[1] - 3.0),
                        plate_thickness_mm=2.0, distortion=(0.0,) * 5, box_rotation_rad=(0.0, 0.0, 0.0))
    return rough.with_errors({name: MirrorError() for name in MIRROR_NAMES})


def check_start(true_rig: Rig, start: Rig | None) -> None:
    """ValueError when the start rig is not of the build's camera: another image size, or a pixel pitch more
    than 1 % off (a calibration starts from the design of the camera it calibrates; a start of another camera
    would be found wrong only after every render)."""
    if start is None:
        return
    a, b = true_rig.camera, start.camera
    if a.image_size_px != b.image_size_px or not np.allclose(a.pixel_pitch_mm, b.pixel_pitch_mm, rtol=0.01):
        raise ValueError(f"the start rig is another camera: {b.image_size_px[0]}x{b.image_size_px[1]} px of "
                         f"{b.pixel_pitch_mm[0] * 1000:g} um, the build's {a.image_size_px[0]}x{a.image_size_px[1]} "
                         f"px of {a.pixel_pitch_mm[0] * 1000:g} um: start from the build's own design")


def check_table1(true_rig: Rig, method: str = "sweep") -> int:
    """The number of renders :func:`run_table1` makes through ``true_rig``, after checking, before any of
    them, that the pattern is found at every depth (:func:`check_pattern_depths`), that the card fits the
    views (``method='grid'``: :func:`~psvs.calibrate.synthetic.check_card_fits`) and that the renders fit
    in memory and time (:func:`~psvs.simulate.render.check_render_work`)."""
    from psvs.calibrate.synthetic import check_card_fits
    from psvs.simulate.render import check_render_work
    if method not in ("sweep", "grid"):
        raise ValueError(f"method must be 'sweep' or 'grid', got {method!r}")
    depths = np.concatenate([SWEEP_Z_MM if method == "sweep" else [], PAPER_TABLE1[:, 0]])
    check_pattern_depths(true_rig, float(depths.min()), float(depths.max()), "Table I's depths")
    if method == "grid":
        check_card_fits(true_rig, CARD, CARD_VIEWS)
    n = (len(SWEEP_Z_MM) if method == "sweep" else CARD_VIEWS) + len(PAPER_TABLE1)
    check_render_work(true_rig, SUPERSAMPLE, n, f"Table I's {n} renders", "a rig with a smaller camera")
    return n


def run_table1(true_rig: Rig, progress=None, start: Rig | None = None, method: str = "sweep") -> Table1:
    """Render the calibration images and the test images through ``true_rig``, calibrate from ``start``
    (default :func:`rough_start`) by the robot sweep (``method='sweep'``) or hand-held card views
    (``'grid'``), and measure the 15 test distances. What cannot be done is refused first
    (:func:`check_table1`)."""
    total = check_table1(true_rig, method)
    check_start(true_rig, start)
    step = 0

    def tick(what):
        nonlocal step
        step += 1
        if progress:
            progress(step, total, what)

    start = rough_start(true_rig) if start is None else start
    if method == "sweep":
        sweep = []
        for z in SWEEP_Z_MM:
            try:               # paired by the start rig's geometry; an image that cannot be is skipped
                det = detect_with_start(pattern_image(true_rig, z, int(z)), start)
                sweep.append((f"sweep_{z:.0f}", z - ROBOT_OFFSET_MM, det))
            except (ValueError, MeasurementError):
                pass
            tick(f"sweep {z:.0f} mm")
        cal = calibrate_sweep(sweep, start)
    else:
        from psvs.calibrate.folder import grid_view
        from psvs.calibrate.synthetic import random_poses, render_grid_shots
        views = []
        for k, pose in enumerate(random_poses(true_rig, CARD, CARD_VIEWS, seed=14)):
            shot, = render_grid_shots(true_rig, CARD, [pose], seed=100 + k)
            views.append(grid_view(f"card_{k:02d}", shot.image, CARD, start))
            tick(f"card view {k + 1}")
        cal = bundle_adjust(views, [], start)
    meas = []
    for z in PAPER_TABLE1[:, 0]:
        try:
            meas.append(measure_pattern(pattern_image(true_rig, z, int(z) + 1), cal.rig))
        except MeasurementError as exc:   # placed at a known distance: the range hint would mislead
            source = "robot sweep" if method == "sweep" else "card views"
            raise MeasurementError(f"the test pattern at {z:g} mm does not measure through the rig calibrated "
                                   f"from the {source} (RMS {cal.rms_px:.3f} px): "
                                   f"{without_range_hint(str(exc))}") from None
        tick(f"test {z:.1f} mm")
    return Table1(cal, PAPER_TABLE1[:, 0].copy(), meas)


def table_markdown(t: Table1) -> str:
    """Table I as Markdown: each depth's Z, diameter and distance, the paper's beside psvs's, then the errors."""
    r, p, s = t.rows(), PAPER_TABLE1, t.summary()
    lines = ["| Z meas. (mm) | Z calc. paper | Z calc. psvs | d calc. paper | d calc. psvs "
             "| a calc. paper | a calc. psvs |",
             "|---:|---:|---:|---:|---:|---:|---:|"]
    lines += [f"| {a[0]:.1f} | {b[1]:.3f} | {a[1]:.3f} | {b[2]:.3f} | {a[2]:.3f} | {b[3]:.3f} | {a[3]:.3f} |"
              for a, b in zip(r, p, strict=True)]
    lines += ["", "| error (d meas. = 10 mm, a meas. = 80 mm) | paper | psvs |", "|---|---:|---:|"]
    errors = (("mean_abs_z_error_mm", "mean \\|Z error\\| (mm)"), ("max_abs_z_error_mm", "max \\|Z error\\| (mm)"),
              ("mean_diameter_error_mm", "mean \\|d error\\| (mm)"),
              ("mean_distance_error_mm", "mean \\|a error\\| (mm)"))
    for key, label in errors:
        lines.append(f"| {label} | {s['paper'][key]:.3f} | {s['ours'][key]:.3f} |")
    return "\n".join(lines) + "\n"


def write_outputs(folder, t: Table1) -> list[Path]:
    """table1.csv, table1.md and fig10.png (Z calc. vs Z meas.; distances vs Z) in ``folder``."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = Path(folder)
    r, p = t.rows(), PAPER_TABLE1
    csv = io.StringIO()
    csv.write("Z_meas_mm,Z_calc_mm,d_calc_mm,a_calc_mm,Z_calc_paper_mm,d_calc_paper_mm,a_calc_paper_mm\n")
    for a, b in zip(r, p, strict=True):
        csv.write(",".join(f"{v:.4f}" for v in (*a, *b[1:])) + "\n")
    write_atomic(folder / "table1.csv", csv.getvalue())
    write_atomic(folder / "table1.md", table_markdown(t))
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    ax[0].plot(r[:, 0], r[:, 0], "k-", lw=0.8, label="ideal")
    ax[0].plot(p[:, 0], p[:, 1], "s", ms=4, label="paper")
    ax[0].plot(r[:, 0], r[:, 1], "o", ms=4, label="psvs")
    ax[0].set_xlabel("Z measured (mm)")
    ax[0].set_ylabel("Z calculated (mm)")
    ax[0].legend()
    ax[1].plot(p[:, 1], p[:, 2], "s", ms=4, label="d, paper")
    ax[1].plot(r[:, 1], r[:, 2], "o", ms=4, label="d, psvs")
    ax[1].plot(p[:, 1], p[:, 3] / 8, "^", ms=4, label="a / 8, paper")
    ax[1].plot(r[:, 1], r[:, 3] / 8, "v", ms=4, label="a / 8, psvs")
    ax[1].axhline(10, color="k", lw=0.8)
    ax[1].set_xlabel("Z calculated (mm)")
    ax[1].set_ylabel("distance (mm)")
    ax[1].legend(fontsize=8)
    fig.suptitle("Fig. 10: calculated vs measured depth; measured distances vs depth")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    write_atomic(folder / "fig10.png", buf.getvalue())
    return [folder / "table1.csv", folder / "table1.md", folder / "fig10.png"]
