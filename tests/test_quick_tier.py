"""The quick tier and its record (tests/support/durations.py): which tests --quick leaves out, the record a
run keeps (merged, atomic, read back by json), and both end to end in a pytest run of a small suite."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.durations import (
    QUICK_FILE_S,
    longest_files_first,
    merged,
    quick_selection,
    read_record,
    write_record,
)

ROOT = Path(__file__).resolve().parents[1]


def test_slow_tests_and_long_files_are_left_out_and_new_ones_run():
    """A file is in or out whole, by its tests' recorded total; a test marked slow is out anyway."""
    ids = ["a.py::fast", "a.py::slow_but_quick", "b.py::one", "b.py::two", "c.py::new", "d.py::at_the_limit"]
    record = {"a.py::fast": 0.2, "a.py::slow_but_quick": 0.1, "b.py::one": QUICK_FILE_S / 2,
              "b.py::two": QUICK_FILE_S / 2 + 0.01, "d.py::at_the_limit": QUICK_FILE_S}
    kept, out = quick_selection(ids, {"a.py::slow_but_quick"}, record)
    assert kept == ["a.py::fast", "c.py::new", "d.py::at_the_limit"]
    assert out == ["a.py::slow_but_quick", "b.py::one", "b.py::two"]


def test_files_run_longest_first_each_kept_together():
    """Files by their tests' recorded total, longest first; a file the record does not know last; each file's
    tests together, in their order; ties in collection order."""
    ids = ["a.py::1", "a.py::2", "b.py::1", "c.py::1", "c.py::2", "d.py::1", "e.py::1"]
    record = {"a.py::1": 1.0, "a.py::2": 1.0, "b.py::1": 5.0, "c.py::1": 0.5, "c.py::2": 3.0, "e.py::1": 2.0}
    assert longest_files_first(ids, record) == ["b.py::1", "c.py::1", "c.py::2", "a.py::1", "a.py::2", "e.py::1",
                                                "d.py::1"]
    assert longest_files_first(ids, {}) == ids


def test_a_partial_run_keeps_the_rest_of_the_record_and_gone_files_drop(tmp_path):
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests" / "test_a.py").write_text("")
    old = {"tests/test_a.py::x": 3.0, "tests/test_a.py::y": 1.0, "tests/test_gone.py::z": 9.0}
    new = {"tests/test_a.py::x": 0.5}
    assert merged(old, new, tmp_path) == {"tests/test_a.py::x": 0.5, "tests/test_a.py::y": 1.0}


def test_the_record_reads_back_by_value(tmp_path):
    path = tmp_path / "durations.json"
    write_record(path, {"t::b": 2.34567, "t::a": 0.1})
    assert json.loads(path.read_text()) == {"t::a": 0.1, "t::b": 2.346}
    assert read_record(path) == {"t::a": 0.1, "t::b": 2.346}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["durations.json"]    # no temporary file left
    assert path.stat().st_mode & 0o777 == 0o644
    assert read_record(tmp_path / "none.json") == {}
    (tmp_path / "bad.json").write_text('["t::a", 1]')
    with pytest.raises(ValueError, match="not a record of test durations"):
        read_record(tmp_path / "bad.json")


SUITE = '''
import time
import pytest

def test_fast():
    pass

def test_long():
    time.sleep(0.3)

@pytest.mark.slow
def test_marked():
    pass

def test_new():
    pass
'''


def _pytest(folder: Path, *args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist",
                           "-p", "tests.support.durations", "-o", "markers=slow", "--rootdir", str(folder),
                           *args, str(folder / "test_small.py")],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)


def test_a_run_records_and_the_quick_tier_reads_it(tmp_path):
    """A run of a small suite records its tests' times; with a record of a quick file, --quick runs its tests
    but the one marked slow; once the record says the file took long, none of them."""
    (tmp_path / "test_small.py").write_text(SUITE)
    record = tmp_path / "rec.json"
    proc = _pytest(tmp_path, "--record-durations", str(record))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    times = json.loads(record.read_text())
    assert set(times) == {f"test_small.py::{n}" for n in ("test_fast", "test_long", "test_marked", "test_new")}
    assert times["test_small.py::test_long"] >= 0.3 > times["test_small.py::test_fast"]
    record.write_text(json.dumps({"test_small.py::test_fast": 0.01}))
    proc = _pytest(tmp_path, "--quick", "--record-durations", str(record), "-vv")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    ran = {line.split("::")[1].split()[0] for line in proc.stdout.splitlines() if " PASSED" in line}
    assert ran == {"test_fast", "test_long", "test_new"}
    assert "3 passed, 1 deselected" in proc.stdout
    record.write_text(json.dumps({"test_small.py::test_fast": 0.01, "test_small.py::test_long": 60.0}))
    proc = _pytest(tmp_path, "--quick", "--record-durations", str(record), "-vv")
    assert "4 deselected" in proc.stdout, proc.stdout
