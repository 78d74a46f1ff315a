"""A first run says that it compiles (psvs._compiled): a kernel never run is found uncompiled, and once run
(its code in Numba's cache for this CPU) no longer; the notice is one line on stderr."""
import importlib
import sys
import textwrap

import numpy as np

from psvs._compiled import QUIET_ENV, announce, uncompiled
from psvs.dense.compiled import MODULES, NOT_CALLED, SOME_RUNS, announce_dense

KERNELS = textwrap.dedent('''
    import numba as nb

    @nb.njit(cache=True)
    def twice(x):
        return 2 * x

    @nb.njit(cache=True, inline="always")
    def inlined(x):
        return x + 1

    @nb.njit(cache=True)
    def never_called(x):
        return x
''')


def test_a_kernel_not_yet_compiled_is_named_and_then_not(tmp_path, monkeypatch, capsys):
    (tmp_path / "fresh_kernels.py").write_text(KERNELS)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delenv(QUIET_ENV, raising=False)
    mod = importlib.import_module("fresh_kernels")
    try:
        assert sorted(uncompiled(["fresh_kernels"])) == ["fresh_kernels.never_called", "fresh_kernels.twice"]
        assert announce("psvs test", ["fresh_kernels"]) is True
        err = capsys.readouterr().err
        assert err.startswith("psvs test: compiling 2 kernels for this machine's CPU, once") and err.count("\n") == 1
        assert mod.twice(np.float64(3.0)) == 6.0
        assert uncompiled(["fresh_kernels"], skip=("fresh_kernels.never_called",)) == []
        monkeypatch.setenv(QUIET_ENV, "1")
        assert announce("psvs test", ["fresh_kernels"]) is False and capsys.readouterr().err == ""
    finally:
        sys.modules.pop("fresh_kernels", None)


def test_the_dense_list_names_real_kernels():
    for name in NOT_CALLED + SOME_RUNS:
        module, attr = name.rsplit(".", 1)
        assert module in MODULES and hasattr(importlib.import_module(module), attr)


def test_kernels_only_some_runs_call_do_not_make_a_run_say_it_compiles(monkeypatch, capsys, tmp_path):
    """A machine that has only run `--fast` keeps the default mode's local winners uncompiled: its next `--fast`
    run compiles nothing and says nothing; a kernel every run calls still makes it say so."""
    import psvs.dense.compiled as dense_compiled
    monkeypatch.delenv(QUIET_ENV, raising=False)
    monkeypatch.setenv("PSVS_CACHE_DIR", str(tmp_path))
    every = [f"{m}.{a}" for m in MODULES for a in ("x",)][:1]
    monkeypatch.setattr(dense_compiled, "uncompiled", lambda modules, skip=(): [k for k in (*SOME_RUNS, *every)
                                                                                if k not in skip])
    assert announce_dense("psvs disparity") is True
    assert capsys.readouterr().err.startswith("psvs disparity: compiling 1 kernels")
    monkeypatch.setattr(dense_compiled, "uncompiled", lambda modules, skip=(): [k for k in SOME_RUNS
                                                                                if k not in skip])
    assert announce_dense("psvs disparity") is False and capsys.readouterr().err == ""


def test_the_notice_is_not_repeated_for_kernels_a_refused_run_never_reaches(monkeypatch, capsys, tmp_path):
    """An image without echo is refused before the band, depth-table and separation kernels run: they stay
    uncompiled, and every later refusal said "compiling 6 kernels" again (issue 41's trial: two lines for a
    refusal). The notice names a set once per machine (psvs's cache folder keeps it); a kernel not named before
    brings it back; a folder it cannot write only brings the notice back next time."""
    import psvs.dense.compiled as dense_compiled
    monkeypatch.delenv(QUIET_ENV, raising=False)
    monkeypatch.setenv("PSVS_CACHE_DIR", str(tmp_path / "cache"))
    later = ["psvs.dense.band._band_costs", "psvs.dense.depth_table._table_kernel"]
    missing = list(later)
    monkeypatch.setattr(dense_compiled, "uncompiled", lambda modules, skip=(): list(missing))
    assert announce_dense("psvs disparity") is True
    assert capsys.readouterr().err.startswith("psvs disparity: compiling 2 kernels")
    import json
    record = json.loads((tmp_path / "cache" / dense_compiled.NOTICE_FILE).read_text())
    assert record["kernels"] == sorted(later) and record["machine"].startswith("numba ")
    assert announce_dense("psvs disparity") is False and capsys.readouterr().err == ""     # the same set
    missing[:] = later[:1]
    assert announce_dense("psvs disparity") is False and capsys.readouterr().err == ""     # fewer
    missing[:] = [*later, "psvs.dense.separate._separate"]
    assert announce_dense("psvs disparity") is True                                       # a new one
    assert capsys.readouterr().err.startswith("psvs disparity: compiling 3 kernels")
    assert announce_dense("psvs disparity") is False and capsys.readouterr().err == ""
    # another install (or psvs updated: its kernels' files changed) compiles again, and says so
    key = record["machine"]
    assert key == dense_compiled._machine() and len(key.split()[-1]) == 16
    monkeypatch.setattr(dense_compiled, "_machine", lambda: key + "-another-install")
    assert announce_dense("psvs disparity") is True
    assert capsys.readouterr().err.startswith("psvs disparity: compiling 3 kernels")
