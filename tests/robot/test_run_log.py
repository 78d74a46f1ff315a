"""A track run's log.csv read back (psvs.robot.run_log): by value against what the writer was given (a log
written from known cycles by psvs.robot.report's columns, read by the csv module independently), and every
refusal one line naming the row and the column. The round trip of a real run's log is in test_track.py."""
import csv
import io

import numpy as np
import pytest

from psvs.robot.run_log import LOG_COLUMNS, read_log_csv


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
