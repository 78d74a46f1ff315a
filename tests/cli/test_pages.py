"""psvs's commands keep NumPy's huge-page advice off (psvs._budget.small_pages; docs/dense.md, Speed): in the
command's process and in what it starts, unless the user set NUMPY_MADVISE_HUGEPAGE, which then holds."""
import os
import subprocess
import sys

import pytest

#: After a command, this process's advice (NumPy's switch returns the value it replaces) and a child's.
PROBE = ("import subprocess, sys\n"
         "from psvs.cli.main import main\n"
         "main(['rig', 'list'])\n"
         "from numpy._core.multiarray import _set_madvise_hugepage as advise\n"
         "child = subprocess.run([sys.executable, '-c', 'from numpy._core.multiarray import _set_madvise_hugepage "
         "as a; print(a(True))'], capture_output=True, text=True).stdout.strip()\n"
         "print('advice', advise(True), child)\n")


@pytest.mark.parametrize(("stated", "expected"), [(None, "advice False False"), ("1", "advice True True"),
                                                  ("0", "advice False False")])
def test_a_command_turns_the_huge_page_advice_off_unless_the_user_set_it(stated, expected):
    env = {k: v for k, v in os.environ.items() if k != "NUMPY_MADVISE_HUGEPAGE"}
    if stated is not None:
        env["NUMPY_MADVISE_HUGEPAGE"] = stated
    out = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == expected


def test_numpy_advises_huge_pages_by_default_here():
    """The probe's premise: without psvs's command and the variable, NumPy advises huge pages (Linux), so the
    test above sees psvs's doing, not NumPy's default."""
    if not sys.platform.startswith("linux"):
        pytest.skip("NumPy advises huge pages on Linux only")
    env = {k: v for k, v in os.environ.items() if k != "NUMPY_MADVISE_HUGEPAGE"}
    out = subprocess.run([sys.executable, "-c", "from numpy._core.multiarray import _set_madvise_hugepage as a; "
                          "print(a(True))"], env=env, capture_output=True, text=True, timeout=120)
    assert out.stdout.strip() == "True"
