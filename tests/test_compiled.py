"""A first run says that it compiles (psvs._compiled): a kernel never run is found uncompiled, and once run
(its code in Numba's cache for this CPU) no longer; the notice is one line on stderr."""
import importlib
import sys
import textwrap

import numpy as np

from psvs._compiled import QUIET_ENV, announce, uncompiled
from psvs.dense.compiled import MODULES, NOT_CALLED

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
    for name in NOT_CALLED:
        module, attr = name.rsplit(".", 1)
        assert module in MODULES and hasattr(importlib.import_module(module), attr)
