"""Whether a command's Numba kernels are compiled for this machine yet, so that a first run says it compiles.

psvs's hot loops are Numba kernels compiled once per machine and kept in ``__pycache__`` (``cache=True``).
A newcomer's first ``psvs disparity`` compiles them all, which takes minutes; without a word it looks hung.
:func:`uncompiled` reads Numba's cache index of each kernel (does it hold an entry for this CPU?) without
compiling or loading anything, and :func:`announce` prints one line when some kernel will compile.
"""
from __future__ import annotations

import importlib
import os
import sys

#: Set (to anything but 0) to keep the notice off stderr (the test suite does: its stderr is checked line by line).
QUIET_ENV = "PSVS_NO_COMPILE_NOTICE"


def uncompiled(modules, skip=()) -> list[str]:
    """The kernels of ``modules`` (names of modules; their own Numba dispatchers with a disk cache, inlined
    ones and the full names in ``skip`` aside) whose cache holds no compiled code for this machine's CPU:
    they will compile on their first call."""
    try:
        import llvmlite.binding as llvm
        from numba.core.registry import CPUDispatcher
        cpu = llvm.get_host_cpu_name()
    except Exception:           # noqa: BLE001  - an unknown Numba: nothing to say
        return []
    missing = []
    for name in modules:
        module = importlib.import_module(name)
        for attr, disp in vars(module).items():
            full = f"{name}.{attr}"
            if (not isinstance(disp, CPUDispatcher) or disp.__module__ != name or full in skip
                    or disp.targetoptions.get("inline") == "always" or disp._cache is None):
                continue
            try:
                index = disp._cache._cache_file._load_index()
            except Exception:   # noqa: BLE001  - Numba's private layout changed: assume it compiles
                index = {}
            if not any(key[1][1] == cpu for key in index):
                missing.append(full)
    return missing


def announce(command: str, modules, skip=()) -> bool:
    """Print one line on stderr when some of ``modules``' kernels will compile on this run (the first on a
    machine, or after an update of psvs or Numba); True if it did."""
    if quiet():
        return False
    missing = uncompiled(modules, skip)
    if missing:
        notice(command, len(missing))
    return bool(missing)


def quiet() -> bool:
    """Whether the notice is kept off stderr (:data:`QUIET_ENV`)."""
    return os.environ.get(QUIET_ENV, "").strip() not in ("", "0")


def notice(command: str, count: int) -> None:
    """The one line that ``count`` kernels compile on this run."""
    print(f"{command}: compiling {count} kernels for this machine's CPU, once (a few minutes; they are "
          "kept for the next runs) ...", file=sys.stderr, flush=True)
