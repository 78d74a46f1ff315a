import numpy as np
import pytest

from psvs.io.atomic import write_atomic
from psvs.io.points import points_csv_text, read_matches_csv, write_points_csv


def test_read_matches(tmp_path):
    p = tmp_path / "m.csv"
    p.write_text("id,u_l,v_l,u_r,v_r\n1,400,239.5,300,239.5\n2,nan,1,2,3\n\n")
    left, right = read_matches_csv(p)
    np.testing.assert_array_equal(left[0], [400, 239.5])
    np.testing.assert_array_equal(right[0], [300, 239.5])
    assert np.isnan(left[1, 0])


@pytest.mark.parametrize("text, message", [
    ("a,b,c,d\n1,2,3,4\n", r"missing column\(s\) u_l, v_l, u_r, v_r"),
    ("", "empty file"),
    ("u_l,v_l,u_r,v_r\n1,2,x,4\n", r":2: not a number: 'x'"),
    ("u_l,v_l,u_r,v_r\n1,2,4_00,4\n", r":2: not a number: '4_00'"),     # trial 47: read as 400
    ("u_l,v_l,u_r,v_r\n1,2,3\n", r":2: expected 4 columns as the header names, got 3$"),
    ("u_l,v_l,u_r,v_r\n1,2,3,4\n1,2,3,4,\n",
     r":3: expected 4 columns as the header names, got 5 \(a trailing comma\?\)"),
    ("u_l,v_l,u_r,v_r\n1,2,3,4,5\n", r":2: expected 4 columns as the header names, got 5$"),
])
def test_bad_csv(tmp_path, text, message):
    p = tmp_path / "m.csv"
    p.write_text(text)
    with pytest.raises(ValueError, match=message):
        read_matches_csv(p)


def test_points_csv_is_lossless_to_1e_9_mm(tmp_path):
    pts = np.array([[1.123456789012, -2.5, 1199.987654321098], [np.nan, np.nan, np.nan]])
    p = tmp_path / "out.csv"
    write_points_csv(p, pts, np.array([True, False]))
    rows = p.read_text().splitlines()
    assert rows[0] == "X_mm,Y_mm,Z_mm,valid"
    vals = [float(v) for v in rows[1].split(",")]
    np.testing.assert_allclose(vals[:3], pts[0], atol=1e-9)
    assert rows[1].endswith(",1") and rows[2] == "nan,nan,nan,0"
    assert points_csv_text(pts[:0], np.zeros(0, bool)) == "X_mm,Y_mm,Z_mm,valid\n"


def test_atomic_write_keeps_old_file_on_error(tmp_path):
    p = tmp_path / "keep.txt"
    p.write_text("old")


    with pytest.raises(TypeError):
        write_atomic(p, 12345)  # not str/bytes: fails while writing
    assert p.read_text() == "old"
    assert [f.name for f in tmp_path.iterdir()] == ["keep.txt"]
    with pytest.raises(FileNotFoundError, match="output folder does not exist"):
        write_atomic(tmp_path / "no" / "x.txt", "data")


def test_points_with_their_depth_sigma_read_back_by_value(tmp_path):
    """The sigma column (before valid): each value back through Python's csv reader; inf and nan kept."""
    import csv
    pts = np.array([[1.5, -2.25, 812.123456789], [0.0, 1.0, 90000.0], [np.nan, np.nan, np.nan]])
    sigma = np.array([0.4567891, np.inf, np.nan])
    p = tmp_path / "out.csv"
    write_points_csv(p, pts, np.array([True, True, False]), sigma)
    with p.open() as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == ["X_mm", "Y_mm", "Z_mm", "Z_sigma_mm", "valid"]
    np.testing.assert_allclose([[float(r[k]) for k in ("X_mm", "Y_mm", "Z_mm")] for r in rows[:2]], pts[:2],
                               atol=1e-9)
    got = [float(r["Z_sigma_mm"]) for r in rows]
    assert abs(got[0] - 0.4567891) < 1e-6 and got[1] == np.inf and np.isnan(got[2])
    assert [r["valid"] for r in rows] == ["1", "1", "0"]


def test_a_table_too_large_for_the_memory_is_refused_before_it_is_read(tmp_path, monkeypatch):
    """Issue 41's trial: a million-row matches file under a 300 MiB limit used 795 MB. Its lines are counted
    (not parsed) and refused at ROW_BYTES (1000) each, naming the file and the count; the same file passes with
    more memory."""
    import re

    from psvs.io.points import check_rows_memory
    p = tmp_path / "m.csv"
    p.write_text("u_l,v_l,u_r,v_r\n" + "400,239.5,300,239.5\n" * 5000)
    monkeypatch.setenv("PSVS_MEMORY_AVAILABLE_MIB", "300")
    assert check_rows_memory(p) == 5001
    monkeypatch.setenv("PSVS_MEMORY_AVAILABLE_MIB", "5")
    with pytest.raises(ValueError, match=rf"^{re.escape(str(p))}: 5001 rows needs about 4\.8 MiB of memory, more "
                                         r"than the 4\.0 MiB available$"):
        check_rows_memory(p)
