"""A track run's ``log.csv`` read back (``psvs track -o RUN`` writes it, :func:`psvs.robot.report.log_csv`): one
row per control cycle, the torch's tip, its target, the seam point the sensor measured, whether it saw the
seam, the torch's deviation from the true seam, the joints and the cycle's times; what the web page's Robot
step draws."""
from __future__ import annotations

import csv
import io
from dataclasses import dataclass

import numpy as np

from psvs.live.log import HEALTH_COLUMNS

#: The columns of log.csv, in order (mm, s, rad, ms; ``valid`` 0 or 1; ``note`` the stop's or a cycle's word).
LOG_COLUMNS = ("t_s", "s_mm", "speed_mm_s", "tcp_x_mm", "tcp_y_mm", "tcp_z_mm", "target_x_mm", "target_y_mm",
               "target_z_mm", "seam_x_mm", "seam_y_mm", "seam_z_mm", "valid", "lateral_mm", "vertical_mm",
               *(f"q{i + 1}_rad" for i in range(6)), "render_ms", "sensor_ms", "control_ms", "note")
#: With the rolling self-check (psvs.robot.drift) four more, as ``psvs live``'s log: its verdict as of the cycle
#: (empty before its first), the twins' field RMS and its uncertainty (px; NaN when it could not judge) and the
#: tiles it judged.
HEALTH_LOG_COLUMNS = tuple(HEALTH_COLUMNS.split(","))
VERDICTS = ("", "healthy", "drifted", "cannot judge")
_SEAM = tuple(LOG_COLUMNS.index(c) for c in ("seam_x_mm", "seam_y_mm", "seam_z_mm"))
_VALID = LOG_COLUMNS.index("valid")
#: Rows a log may hold (a 10-minute run at 250 Hz): a larger text is not a run's log.
MAX_ROWS = 150_000


@dataclass(frozen=True, eq=False)
class RunLog:
    """A run's cycles: ``t_s`` (n,), the torch's progress along the seam ``s_mm`` (n,), ``tcp_mm``, ``target_mm``,
    ``seam_mm`` (n, 3; NaN where the sensor saw no
    seam) in the robot's base frame, ``valid`` (n,) bool (the sensor saw the seam), ``lateral_mm``
    and ``vertical_mm`` (n,) the torch's deviation from the true seam, ``notes`` (n,) str, ``q_rad`` (n, 6) the
    arm's joint angles; with the self-check
    ``health`` (n,) its verdict as of each cycle ('' before its first) and ``row_offset_rms_px`` (n,) its figure
    (NaN where it had none), else None each."""

    t_s: np.ndarray
    s_mm: np.ndarray
    tcp_mm: np.ndarray
    target_mm: np.ndarray
    seam_mm: np.ndarray
    valid: np.ndarray
    lateral_mm: np.ndarray
    vertical_mm: np.ndarray
    notes: tuple
    health: tuple | None = None
    row_offset_rms_px: np.ndarray | None = None
    q_rad: np.ndarray | None = None

    def welded(self, arc_on_mm: float, arc_struck: bool = True) -> np.ndarray:
        """Mask (n,) of the cycles with the arc on (the torch's progress at ``arc_on_mm`` or beyond: the run-in
        before it fills the sensor's look-ahead); none when the arc was never struck (report.json's
        ``stop.arc_struck``: a halt before it, as :func:`psvs.robot.report.arc_on` has it)."""
        return (self.s_mm >= arc_on_mm) & bool(arc_struck)


def read_log_csv(text: str, where: str = "log.csv") -> RunLog:
    """A run's log from its text; ValueError naming ``where``, the row and the column for anything else than
    what :func:`psvs.robot.report.log_csv` writes (another header, a value that is not a finite number, valid
    not 0 or 1, no row, too many, a field longer than the csv module reads)."""
    try:
        return _read_log(text, where)
    except csv.Error as exc:
        raise ValueError(f"{where} is not a psvs track log: {exc}") from None


def _read_log(text: str, where: str) -> RunLog:
    rows = csv.reader(io.StringIO(text))
    header = next(rows, None)
    names = None if header is None else tuple(h.strip() for h in header)
    checked = names == LOG_COLUMNS + HEALTH_LOG_COLUMNS
    if not checked and names != LOG_COLUMNS:
        got = ", ".join(header[:4]) + (" ..." if header and len(header) > 4 else "") if header else "nothing"
        raise ValueError(f"{where} is not a psvs track log: its header is {got}, expected {', '.join(LOG_COLUMNS[:4])} "
                         f"... ({len(LOG_COLUMNS)} columns)")
    values, notes, health = [], [], []
    for k, row in enumerate(rows, start=2):
        if not row:
            continue
        if len(values) >= MAX_ROWS:
            raise ValueError(f"{where} holds more than {MAX_ROWS} rows: not one run's log")
        if len(row) != len(names):
            raise ValueError(f"{where} row {k}: {len(row)} values, expected {len(names)}")
        if checked:
            health.append(_health_cells(row[len(LOG_COLUMNS):], where, k))
            row = row[:len(LOG_COLUMNS)]
        try:
            nums = [float(v) for v in row[:-1]]
        except ValueError:
            col = next(c for c, v in zip(LOG_COLUMNS, row[:-1], strict=False) if not _is_number(v))
            raise ValueError(f"{where} row {k}: {col} is not a number") from None
        blind = nums[_VALID] == 0.0          # no seam seen: its seam point is NaN
        bad = [i for i, v in enumerate(nums) if not np.isfinite(v) and not (blind and i in _SEAM and np.isnan(v))]
        if bad:
            col = LOG_COLUMNS[bad[0]]
            raise ValueError(f"{where} row {k}: {col} is not finite")
        if nums[_VALID] not in (0.0, 1.0):
            raise ValueError(f"{where} row {k}: valid must be 0 or 1")
        values.append(nums)
        notes.append(row[-1])
    if not values:
        raise ValueError(f"{where} holds no cycle")
    a = np.array(values)
    col = lambda *names: a[:, [LOG_COLUMNS.index(n) for n in names]]  # noqa: E731
    one = lambda name: a[:, LOG_COLUMNS.index(name)]  # noqa: E731
    return RunLog(one("t_s"), one("s_mm"), col("tcp_x_mm", "tcp_y_mm", "tcp_z_mm"),
                  col("target_x_mm", "target_y_mm", "target_z_mm"), col("seam_x_mm", "seam_y_mm", "seam_z_mm"),
                  one("valid") == 1.0, one("lateral_mm"), one("vertical_mm"), tuple(notes),
                  tuple(h[0] for h in health) if checked else None,
                  np.array([h[1] for h in health]) if checked else None, col(*(f"q{i + 1}_rad" for i in range(6))))


def _health_cells(cells: list[str], where: str, k: int) -> tuple[str, float]:
    """A row's self-check columns read: (verdict, field RMS px or NaN); ValueError naming the row and column."""
    verdict, rms, unc, tiles = (c.strip() for c in cells)
    if verdict not in VERDICTS:
        raise ValueError(f"{where} row {k}: health must be empty or one of {', '.join(VERDICTS[1:])}")
    for name, v in (("row_offset_rms_px", rms), ("row_offset_unc_px", unc), ("health_tiles", tiles)):
        if v and not (_is_number(v) and not np.isinf(float(v))):
            raise ValueError(f"{where} row {k}: {name} is not a number")
        if not verdict and v:
            raise ValueError(f"{where} row {k}: {name} without a verdict")
    if tiles and (float(tiles) < 0 or float(tiles) != int(float(tiles))):
        raise ValueError(f"{where} row {k}: health_tiles must be a count")
    return verdict, float(rms) if rms else float("nan")


def _is_number(v: str) -> bool:
    try:
        float(v)
    except ValueError:
        return False
    return True
