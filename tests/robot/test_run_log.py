"""A track run's log.csv read back (psvs.robot.run_log): by value against what the writer was given (a log
written from known cycles by psvs.robot.report's columns, read by the csv module independently), and every
refusal one line naming the row and the column. The round trip of a real run's log is in test_track.py."""
import csv
import io

import numpy as np
import pytest

from psvs.robot.run_log import HEALTH_LOG_COLUMNS, LOG_COLUMNS, read_log_csv


def _log(rows) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(LOG_COLUMNS)
    w.writerows(rows)
    return buf.getvalue()


def _row(k: int, valid: int = 1, note: str = "") -> list:
    rng = np.random.default_rng(k)
    nums = rng.uniform(-500, 500, len(LOG_COLUMNS) - 1).round(4)
    nums[0], nums[1], nums[LOG_COLUMNS.index("valid")] = 0.04 * k, 0.5 * k, valid
    return [*(f"{v:.4f}" for v in nums), note]


def test_a_log_reads_back_by_value():
    rows = [_row(k, valid=k % 3 != 0) for k in range(40)] + [_row(40, note="weld length reached")]
    log = read_log_csv(_log(rows))
    table = list(csv.DictReader(io.StringIO(_log(rows))))
    col = lambda *names: np.array([[float(r[n]) for n in names] for r in table])  # noqa: E731
    np.testing.assert_array_equal(log.tcp_mm, col("tcp_x_mm", "tcp_y_mm", "tcp_z_mm"))
    np.testing.assert_array_equal(log.seam_mm, col("seam_x_mm", "seam_y_mm", "seam_z_mm"))
    np.testing.assert_array_equal(log.target_mm, col("target_x_mm", "target_y_mm", "target_z_mm"))
    np.testing.assert_array_equal(log.lateral_mm, col("lateral_mm")[:, 0])
    assert log.valid.tolist() == [r["valid"] == "1.0000" for r in table]
    assert log.notes[-1] == "weld length reached" and log.notes[0] == ""
    assert log.welded(10.0).tolist() == [0.5 * k >= 10.0 for k in range(41)]
    assert not log.welded(10.0, arc_struck=False).any()        # halted before the arc: never struck


@pytest.mark.parametrize("text, said", [
    ("", "is not a psvs track log: its header is nothing"),
    ("a,b,c\n1,2,3\n", "is not a psvs track log: its header is a, b, c"),
    (_log([]), "holds no cycle"),
    (_log([_row(1)[:-3]]), "row 2: 22 values, expected 25"),
    (_log([_row(1), [*_row(2)[:5], "x", *_row(2)[6:]]]), "row 3: tcp_z_mm is not a number"),
    (_log([[*_row(1)[:13], "nan", *_row(1)[14:]]]), "row 2: lateral_mm is not finite"),
    (_log([_row(1, valid=2)]), "row 2: valid must be 0 or 1"),
])
def test_what_is_not_a_log_is_refused_in_one_line(text, said):
    with pytest.raises(ValueError, match=said) as exc:
        read_log_csv(text, "run/log.csv")
    assert str(exc.value).startswith("run/log.csv ") and "\n" not in str(exc.value)


def _checked_log(rows, health) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(LOG_COLUMNS + HEALTH_LOG_COLUMNS)
    w.writerows(r + h for r, h in zip(rows, health, strict=True))
    return buf.getvalue()


def test_a_log_with_the_self_check_reads_back_by_value():
    """The self-check's columns (psvs track's default): the verdict as of each cycle, '' before its first,
    its figure NaN where it could not judge; the run's columns as without them."""
    rows = [_row(k) for k in range(6)]
    health = [["", "", "", ""], ["cannot judge", "nan", "nan", "7"], ["healthy", "0.1200", "0.0500", "40"],
              ["healthy", "0.1300", "0.0400", "52"], ["drifted", "2.6600", "0.4800", "14"],
              ["drifted", "2.7000", "0.3000", "30"]]
    log = read_log_csv(_checked_log(rows, health))
    assert log.health == tuple(h[0] for h in health)
    np.testing.assert_array_equal(log.row_offset_rms_px, [np.nan, np.nan, 0.12, 0.13, 2.66, 2.70])
    plain = read_log_csv(_log(rows))
    np.testing.assert_array_equal(log.tcp_mm, plain.tcp_mm)
    assert plain.health is None and plain.row_offset_rms_px is None


@pytest.mark.parametrize("cells, said", [
    (["fine", "0.1", "0.1", "3"], "row 2: health must be empty or one of healthy, drifted, cannot judge"),
    (["healthy", "x", "0.1", "3"], "row 2: row_offset_rms_px is not a number"),
    (["healthy", "0.1", "inf", "3"], "row 2: row_offset_unc_px is not a number"),
    (["", "0.1", "", ""], "row 2: row_offset_rms_px without a verdict"),
    (["healthy", "0.1", "0.1", "2.5"], "row 2: health_tiles must be a count"),
])
def test_a_bad_self_check_cell_is_refused_in_one_line(cells, said):
    with pytest.raises(ValueError, match=said) as exc:
        read_log_csv(_checked_log([_row(1)], [cells]), "run/log.csv")
    assert str(exc.value).startswith("run/log.csv ") and "\n" not in str(exc.value)


def test_a_field_beyond_the_csv_modules_limit_is_refused_in_one_line():
    text = _log([_row(1, note="x" * 200_000)])
    with pytest.raises(ValueError, match="run/log.csv is not a psvs track log: field larger than field limit"):
        read_log_csv(text, "run/log.csv")
