"""The quick tier of the suite and the record it is chosen from (a pytest plugin of the root conftest).

- ``--record-durations FILE``: each test's time (setup + call + teardown, s, as the worker that ran it
  measured) merged into FILE (JSON) when the session ends, atomically. ``python3 dev.py test`` (the whole
  suite) keeps ``tests/durations.json`` so, and the record follows the suite.
- ``--quick``: the edit-test loop. The tests marked ``slow`` are left out, and so is every test of a file
  whose tests together took more than :data:`QUICK_FILE_S` in the record (``--record-durations FILE`` when
  given, else ``tests/durations.json``); a test the record does not know (a new one) runs. The tests left
  out are counted in the summary line ("deselected").

- Every run takes the test files longest first by the record (:func:`longest_files_first`), each file's
  tests in their own order: ``python3 dev.py test`` hands files to its xdist workers in that order
  (``--no-loadscope-reorder``, pytest-xdist 3.8), so the longest start first and the short ones fill in at
  the end, instead of a 7-minute file starting when the other worker is nearly done.

Whole files, not single tests: a file's costly shared fixture (a module's render or calibration) is timed
with the first test that uses it, and leaving that test out would only move the cost to the next one (a
per-test limit of 1.5 s kept 139 s of recorded tests and ran 254 s). The record of a machine under load is
longer, which makes the tier smaller, never wrong.
"""
from __future__ import annotations

import json
import os
import tempfile
from collections import defaultdict
from pathlib import Path

#: s: the longest a test file's tests may have taken together in the record to run in the quick tier.
QUICK_FILE_S = 8.0
#: The record ``python3 dev.py test`` keeps (``--record-durations``) and ``--quick`` reads.
RECORD = Path(__file__).resolve().parents[1] / "durations.json"


def pytest_addoption(parser):
    group = parser.getgroup("psvs")
    group.addoption("--quick", action="store_true",
                    help=f"the quick tier: no test marked slow nor any of a file whose tests took over "
                         f"{QUICK_FILE_S:g} s in {RECORD.name}")
    group.addoption("--record-durations", metavar="FILE", default=None,
                    help="write each test's time (setup + call + teardown, s) to FILE as JSON")


_times: dict[str, float] = defaultdict(float)


def pytest_runtest_logreport(report):
    """Every phase's report reaches the controller (also from xdist's workers)."""
    _times[report.nodeid] += float(report.duration)


def quick_selection(nodeids: list[str], slow: set[str], record: dict[str, float],
                    limit_s: float = QUICK_FILE_S) -> tuple[list[str], list[str]]:
    """(kept, left out) of ``nodeids``: out when marked ``slow`` or when its file's recorded tests took more
    than ``limit_s`` together."""
    per_file = file_totals(record)
    out = [n for n in nodeids if n in slow or per_file.get(n.split("::")[0], 0.0) > limit_s]
    gone = set(out)
    return [n for n in nodeids if n not in gone], out


def file_totals(record: dict[str, float]) -> dict[str, float]:
    """Each test file's recorded total (s), by path, from a record of node ids."""
    per_file: dict[str, float] = defaultdict(float)
    for node, seconds in record.items():
        per_file[node.split("::")[0]] += seconds
    return per_file


def longest_files_first(nodeids: list[str], record: dict[str, float]) -> list[str]:
    """``nodeids`` with their files ordered by their tests' recorded total, longest first (files the record does
    not know last), each file's tests kept together in their order."""
    per_file = file_totals(record)
    first: dict[str, int] = {}
    for k, n in enumerate(nodeids):
        first.setdefault(n.split("::")[0], k)
    return sorted(nodeids, key=lambda n: (-per_file.get(n.split("::")[0], 0.0), first[n.split("::")[0]]))


def read_record(path: Path = RECORD) -> dict[str, float]:
    """The recorded times (node id -> s); empty when there is no record yet."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return {}
    if not isinstance(data, dict) or not all(isinstance(v, (int, float)) for v in data.values()):
        raise ValueError(f"{path}: not a record of test durations (node id -> seconds)")
    return {str(k): float(v) for k, v in data.items()}


def pytest_collection_modifyitems(config, items):
    given = config.getoption("record_durations")
    record = read_record(Path(given) if given else RECORD)
    if config.getoption("quick"):
        slow = {it.nodeid for it in items if it.get_closest_marker("slow")}
        kept, out = quick_selection([it.nodeid for it in items], slow, record)
        gone = set(out)
        config.hook.pytest_deselected(items=[it for it in items if it.nodeid in gone])
        items[:] = [it for it in items if it.nodeid not in gone]
    at = {it.nodeid: it for it in items}
    items[:] = [at[n] for n in longest_files_first([it.nodeid for it in items], record)]


def write_record(path: Path, times: dict[str, float]) -> None:
    """``times`` as sorted JSON at ``path``, written atomically (a temporary file renamed)."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=path.name, dir=path.parent)
    os.chmod(tmp, 0o644)                # a file of the repository, not a private temporary one
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        json.dump({k: round(v, 3) for k, v in sorted(times.items())}, f, indent=0)
        f.write("\n")
    os.replace(tmp, path)


def merged(old: dict[str, float], new: dict[str, float], root: Path) -> dict[str, float]:
    """``old`` updated with ``new`` (a run of part of the suite keeps the rest of the record), less the
    tests whose file is gone."""
    both = {**old, **new}
    return {k: v for k, v in both.items() if (root / k.split("::")[0]).exists()}


def pytest_sessionfinish(session):
    target = session.config.getoption("record_durations")
    if target and not hasattr(session.config, "workerinput") and _times:
        path = Path(target)
        write_record(path, merged(read_record(path), _times, Path(session.config.rootpath)))
