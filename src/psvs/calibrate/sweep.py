"""The paper's robot sweep: the circle pattern moved along Z, positions read off the robot.

``sweep.csv`` (columns ``image,position_mm``) lists the images and the robot's Z readings, which differ from
the pattern's depth in frame C by an unknown offset. The pattern's pose on the robot (the direction of its
row of circles, angles ry and rz, and its lateral position x0, y0) is constant while the robot moves along
Z; a rotation about the row itself cannot be seen in the circle centres, so it is not a parameter. The
sweep is calibrated by the same bundle adjustment as hand-held grid views
(:func:`psvs.calibrate.bundle.bundle_adjust`), alone or together with them.
"""
from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

from psvs.calibrate.bundle import BundleResult, SweepView, bundle_adjust
from psvs.errors import MeasurementError
from psvs.io.images import read_grey
from psvs.io.text import read_csv_rows
from psvs.optics.rig import Rig
from psvs.targets.pattern import PatternDetection, detect_pattern

SPACING_MM = 20.0   # the paper's pattern: circles 20 mm apart (Fig. 9)
COUNT = 5


def pattern_layout(count: int = COUNT, spacing_mm: float = SPACING_MM) -> np.ndarray:
    """The pattern's circle centres in its own frame (count, 3), mm: a row along x, centred."""
    return np.column_stack([(np.arange(count) - (count - 1) / 2) * spacing_mm, np.zeros(count), np.zeros(count)])


def dumps_sweep(rows: list[tuple[str, float]]) -> str:
    """``sweep.csv`` text: a header ``image,position_mm`` and one row per (image file name, robot reading mm);
    the readings are written with repr precision, so :func:`read_sweep` gets the same floats back."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["image", "position_mm"])
    w.writerows((name, repr(float(z))) for name, z in rows)
    return buf.getvalue()


def read_sweep(folder) -> list[tuple[Path, float]]:
    """(image path, robot position mm) from ``folder/sweep.csv`` (columns image,position_mm)."""
    folder = Path(folder)
    table = folder / "sweep.csv"
    if not table.is_file():
        raise FileNotFoundError(f"sweep file not found: {table}")
    rows = read_csv_rows(table)
    header = rows[0] if rows else None
    if header is None or not {"image", "position_mm"} <= set(header):
        raise ValueError(f"{table}: expected columns image,position_mm, got {header}")
    col = {name: header.index(name) for name in ("image", "position_mm")}
    out = []
    for n, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) <= max(col.values()):
            raise ValueError(f"{table}:{n}: expected columns image,position_mm, got {len(row)} cells")
        image, position = row[col["image"]], row[col["position_mm"]]
        try:
            value = float(position)
        except ValueError:
            raise ValueError(f"{table}:{n}: position_mm is not a number: {position!r}") from None
        if not math.isfinite(value):
            raise ValueError(f"{table}:{n}: position_mm must be a finite robot reading (mm), got {position!r}")
        out.append((folder / image, value))
    if not out:
        raise ValueError(f"{table}: no images listed")
    check_sweep_rows(out, table.name)
    return out


def check_sweep_rows(items: list[tuple[Path | str, float]], where: str = "the sweep") -> None:
    """ValueError naming the duplicates when the sweep lists one image twice (the same file, by name or by
    its resolved path) or one robot position for two images: a repeated row adds no view and no position,
    yet the bundle adjustment would weigh it as new evidence and count it as an image used."""
    seen: dict = {}
    for name, _ in items:
        key = Path(name).resolve() if isinstance(name, Path) else name
        seen.setdefault(key, []).append(Path(name).name)
    for names in seen.values():
        if len(names) > 1:
            raise ValueError(f"{where} lists {names[0]} {len(names)} times: each row must be its own image")
    at: dict[float, list[str]] = {}
    for name, pos in items:
        at.setdefault(float(pos), []).append(Path(name).name)
    for pos, names in at.items():
        if len(names) > 1:
            raise ValueError(f"{where} lists robot position {pos:g} mm for {len(names)} images ({', '.join(names)}): "
                             "each sweep image must be at its own position")


def detect_sweep(items: list[tuple[Path, float]], count: int = 5, expect_size: tuple[int, int] | None = None,
                 start: Rig | None = None):
    """Detect the pattern in every image (of ``expect_size`` (W, H) px when given: the camera's), its two
    views paired by the ``start`` rig's geometry when given (:func:`psvs.targets.pattern.detect_with_start`),
    else split by u (:func:`psvs.targets.pattern.detect_pattern`); returns ([(name, position, detection)],
    {name: error})."""
    from psvs.targets.pattern import detect_with_start
    ok, skipped = [], {}
    for path, pos in items:
        try:
            grey = read_grey(path, expect_size=expect_size)
            det = detect_pattern(grey, count) if start is None else detect_with_start(grey, start, count, SPACING_MM)
            ok.append((path.name, pos, det))
        except (ValueError, FileNotFoundError, MeasurementError) as exc:
            skipped[path.name] = str(exc)
    return ok, skipped


def sweep_views(observations: list[tuple[str, float, PatternDetection]]) -> list[SweepView]:
    """Bundle-adjustment views of sweep detections [(name, robot position mm, detection)]."""
    return [SweepView(name, float(pos), np.array([e.centre_px for e in det.left]),
                      np.array([e.centre_px for e in det.right])) for name, pos, det in observations]


def calibrate_sweep(observations, start: Rig, count: int = COUNT) -> BundleResult:
    """Calibrate from sweep detections [(name, robot position mm, PatternDetection)] alone, from ``start``."""
    check_sweep_rows([(name, pos) for name, pos, _ in observations])
    if len(observations) < 3:
        raise ValueError(f"calibration needs at least 3 usable sweep images, got {len(observations)}")
    return bundle_adjust([], sweep_views(observations), start, sweep_local_mm=pattern_layout(count))
