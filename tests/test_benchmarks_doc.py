"""docs/benchmarks.md, as bench/run.py wrote it, read back by value: each case's verdict agrees with its time
and target, and each ratio (e.g. the dense default mode over OpenCV's StereoSGBM 3-way on all cores, the
reference) equals the quotient of its two cases' times in the same table."""
import datetime
import importlib.util
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "benchmarks.md"


def _table_rows(text: str, cells: int) -> list[list[str]]:
    rows = []
    for line in text.splitlines():
        parts = [c.strip() for c in line.strip().strip("|").split("|")]
        header = parts[0] in ("group", "") or parts[0].startswith("-")
        if line.startswith("|") and len(parts) == cells and not header:
            rows.append(parts)
    return rows


@pytest.fixture(scope="module")
def doc():
    text = DOC.read_text(encoding="utf-8")
    cases = {(g, name): (float(t), None if target == "—" else float(target), met)
             for g, name, t, target, met in _table_rows(text, 5)}
    ratios = {(g, name): float(v) for g, name, v in _table_rows(text, 3)}
    return text, cases, ratios


def test_the_machine_and_the_date_are_named(doc):
    text, _, _ = doc
    date = re.search(r"^- Date: (\d{4}-\d{2}-\d{2})$", text, re.M)
    assert date and datetime.date.fromisoformat(date.group(1))
    assert re.search(r"^- Machine: .+, \d+ cores, Python 3\.\d+", text, re.M)


def test_the_last_run_names_groups_of_the_table(doc):
    """The date and load are the last run's; it names the groups it measured (the other rows are older)."""
    text, cases, _ = doc
    last = re.search(r"^- The last run measured ([a-z0-9_, ]+?)(?: \(cases matching .*\))?(;.*)?$", text, re.M)
    assert last, "no '- The last run measured ...' line"
    groups = set(last.group(1).split(", "))
    assert groups and groups <= {g for g, _ in cases}
    if groups != {g for g, _ in cases}:
        assert last.group(2) == "; the other rows are from earlier runs"


def test_each_verdict_agrees_with_its_time_and_target(doc):
    _, cases, _ = doc
    assert len(cases) >= 20
    for (group, name), (t, target, met) in cases.items():
        assert t > 0, name
        if target is None:
            assert met == "—", name
        else:
            assert met == ("yes" if t <= target else "NO"), name


def test_each_ratio_is_the_quotient_of_its_cases(doc):
    _, cases, ratios = doc
    found = 0
    for path in sorted((ROOT / "bench").glob("bench_*.py")):
        spec = importlib.util.spec_from_file_location(path.stem, path)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        group = path.stem.removeprefix("bench_")
        for name, a, b in getattr(mod, "RATIOS", []):
            value = ratios[(group, name)]
            assert value == pytest.approx(cases[(group, a)][0] / cases[(group, b)][0], rel=0.01), name
            found += 1
    assert found >= 2     # the dense default mode over StereoSGBM 3-way on all cores (the reference), on 1 thread


def test_help_and_unknown_groups_write_nothing(capsys):
    """``bench/run.py --help`` prints its usage and an unknown option, group or case exits 2, all before any case
    runs: docs/benchmarks.md is left as it was."""
    spec = importlib.util.spec_from_file_location("bench_run", ROOT / "bench" / "run.py")
    run = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(run)
    before = DOC.read_bytes()
    assert run.main(["--help"]) == 0 and "Run the benchmarks" in capsys.readouterr().err
    assert run.main(["--bogus"]) == 2
    assert run.main(["nosuchgroup"]) == 2 and "groups: calibrate" in capsys.readouterr().err
    assert run.main(["triangulate", "--case", "no such case"]) == 2 and "no case matches" in capsys.readouterr().err
    assert DOC.read_bytes() == before


@pytest.mark.slow     # renders the 1440 x 1080 frame the case matches on (about 10 s)
def test_a_ratio_of_which_one_case_ran_again_is_left_out(tmp_path, monkeypatch, capsys):
    """bench/run.py re-measuring one case of a ratio (``--case``) drops that ratio's old row: its other case
    is of an earlier run, and the quotient of two runs is no ratio of the same run (the live loop's was kept
    stale once). The other rows stay."""
    spec = importlib.util.spec_from_file_location("bench_run", ROOT / "bench" / "run.py")
    run = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(run)
    out = tmp_path / "benchmarks.md"
    out.write_text(DOC.read_text(encoding="utf-8"), encoding="utf-8")
    monkeypatch.setattr(run, "OUT", out)
    before = {(g, n) for g, n, _ in _table_rows(out.read_text(encoding="utf-8"), 3)}
    paper = ("match", "mv1440 1440x1080 / 640x480, paper chain (same run)")
    assert paper in before
    run.main(["match", "--case", "mv1440 1440x1080: pipeline + seeded"])
    assert "left out (only one of its two cases ran)" in capsys.readouterr().out
    after = {(g, n) for g, n, _ in _table_rows(out.read_text(encoding="utf-8"), 3)}
    assert after == before - {paper}
