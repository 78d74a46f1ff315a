"""The run folder's Parquet files without a cluster: rows checked, parts read once per key, merged, a
half-written part ignored; the progress bar's plain lines."""
import io

import numpy as np
import pyarrow.parquet as pq
import pytest

from psvs.cluster.progress import Progress
from psvs.cluster.store import ResultStore, check_row, read_results, record_params


def test_rows_are_flat_scalars_with_their_key():
    assert check_row({"a": np.float64(1.5), "b": np.int32(2), "c": None, "d": "x", "e": True}, 7) == \
        {"key": 7, "a": 1.5, "b": 2, "c": None, "d": "x", "e": True}
    with pytest.raises(TypeError, match="b is a list"):
        check_row({"b": [1, 2]}, 1)
    with pytest.raises(TypeError, match="column names"):
        check_row({"key": 1}, 1)
    with pytest.raises(TypeError, match="dict of scalars"):
        check_row(3.0, 1)


def test_parts_are_read_once_per_key_merged_and_a_temporary_file_ignored(tmp_path):
    record_params(tmp_path, {"seed": 1})
    store = ResultStore(tmp_path)
    store.append([{"key": 2, "x": 2.0, "s": "b"}, {"key": 0, "x": None, "s": "a"}])
    store.append([{"key": 1, "x": 1, "extra": True}])          # an int where floats were, a new column
    store.append([{"key": 2, "x": 99.0, "s": "dup"}])         # written twice (a crash between merge and unlink)
    (tmp_path / "parts" / ".part-000009.parquet.abc.tmp").write_bytes(b"half a file")
    rows = read_results(tmp_path).to_pylist()
    assert [r["key"] for r in rows] == [0, 1, 2]
    assert rows[2]["x"] == 2.0 and rows[2]["s"] == "b" and rows[1]["extra"] is True and rows[0]["extra"] is None
    store.compact()
    assert read_results(tmp_path).to_pylist() == rows
    assert pq.read_table(tmp_path / "results.parquet").num_rows == 3
    assert not list((tmp_path / "parts").glob("part-*.parquet"))


def test_a_folder_without_a_run_and_an_empty_run(tmp_path):
    with pytest.raises(FileNotFoundError, match="no run in"):
        read_results(tmp_path)
    record_params(tmp_path, {})
    assert read_results(tmp_path).num_rows == 0


def test_a_damaged_parameter_file_is_refused(tmp_path):
    (tmp_path / "study.json").write_text("{not json")
    with pytest.raises(ValueError, match="not a run's parameter file"):
        record_params(tmp_path, {"a": 1})


def test_the_progress_bar_writes_plain_lines_to_a_log():
    out = io.StringIO()
    bar = Progress("work", 20, skipped=5, stream=out)
    for _ in range(20):
        bar.update(1)
    bar.close()
    lines = out.getvalue().splitlines()
    assert len(lines) == 10 and lines[-1].startswith("work: 20/20 (5 done before)")
    assert "\r" not in out.getvalue()


def test_the_progress_bar_redraws_one_line_on_a_terminal():
    class Terminal(io.StringIO):
        def isatty(self):
            return True
    out = Terminal()
    bar = Progress("work", 4, stream=out)
    bar.update(4, 1)
    bar.close()
    text = out.getvalue()
    assert text.startswith("\rwork [") and text.endswith("\n") and text.count("\n") == 1
    assert "4/4, 1 failed" in text and "#" * 30 in text


def test_forgotten_keys_leave_the_results_and_the_rest_stay_by_value(tmp_path):
    """ResultStore.forget: the parts merged, the named keys' rows gone from results.parquet (read back by
    pyarrow directly), every other row as written; forgetting nothing or an unknown key changes nothing."""
    record_params(tmp_path, {"n": 3})
    store = ResultStore(tmp_path)
    store.append([{"key": "a", "v": 1.5}, {"key": "b", "v": 2.5}])
    store.append([{"key": "c", "v": 3.5}])
    store.forget([])
    assert (tmp_path / "parts").is_dir()            # nothing to forget: the parts as they were
    store.forget(["b", "zz"])
    assert not (tmp_path / "parts").exists()
    assert pq.read_table(tmp_path / "results.parquet").to_pylist() == [{"key": "a", "v": 1.5}, {"key": "c", "v": 3.5}]
    assert store.done_keys() == {"a", "c"}
