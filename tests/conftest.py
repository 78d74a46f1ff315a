import atexit
import os
import shutil
import tempfile

import pytest

from psvs import default_rig
from psvs._budget import small_pages
from psvs.io.params import load_rig
from psvs.optics.design import design_mirrors
from tests.reference_optics import ReferenceRig
from tests.support.geometry import EXAMPLES
from tests.support.video import write_hand_video, write_wall_video

#: plugins of the whole suite: the browser tests' Chromium page (tests/support/browser.py), the quick tier and
#: the record of durations it is chosen from (tests/support/durations.py), the session's renders kept by content
#: (tests/support/render_cache.py)
pytest_plugins = ["tests.support.browser", "tests.support.durations", "tests.support.render_cache"]

#: The session's own cache folder (psvs.dense.rig_cache): the tests never read or write the user's, and each
#: session starts empty. Set at import, before any test or command runs (subprocesses inherit it); removed
#: when the process ends (also when a script, not pytest, imports this module).
SESSION_CACHE = tempfile.mkdtemp(prefix="psvs-test-cache-")
os.environ["PSVS_CACHE_DIR"] = SESSION_CACHE
atexit.register(shutil.rmtree, SESSION_CACHE, ignore_errors=True)
#: A fresh clone's first dense command says that it compiles (psvs._compiled); the tests check commands'
#: stderr line by line, and which test compiles first is chance: the notice is off (tests/test_compiled.py on).
os.environ["PSVS_NO_COMPILE_NOTICE"] = "1"
#: NumPy's huge-page advice off, as psvs's commands have it (psvs._budget.small_pages): the tests that run a
#: library call in this process then measure what a command does, and on this machine's kernel the dense tests
#: took 52-54 s against 64-66 s with the advice (docs/dense.md, Speed). Workers and subprocesses inherit it.
small_pages()
#: The memory guard (psvs._budget) sees 8 GiB, whatever else the machine runs: a test's refusal or answer must
#: not depend on the free memory of the moment (a fresh clone failed once with 196 MiB free). Tests of the
#: guard itself set their own figure.
os.environ["PSVS_MEMORY_AVAILABLE_MIB"] = "8192"


def pytest_sessionfinish(session):
    """The session's shared files (tests/support/shared_files.py) removed by the pytest process."""
    if not hasattr(session.config, "workerinput"):
        from tests.support.shared_files import remove_session_folder
        remove_session_folder()


def pytest_configure(config):
    """Under pytest-xdist, dev.py shares the cores out (PSVS_WORKER_THREADS): each worker's Numba kernels run
    on its share of them, so that two workers do not each start a thread per core (tests/dense/test_threads.py
    checks the kernels on every core)."""
    share = os.environ.get("PSVS_WORKER_THREADS")
    if share and hasattr(config, "workerinput"):
        import numba
        numba.set_num_threads(max(1, min(int(share), numba.config.NUMBA_NUM_THREADS)))


@pytest.fixture
def rig():
    """The default rig (f 11.3, b 100, 3 mm plate, n 1.52), ideal unbounded mirrors."""
    return default_rig()


@pytest.fixture(scope="session")
def clear_rig():
    """examples/rigs/clear.toml: M1 at 22 mm, M2 at 44 mm, with its designed mirror extents."""
    rig = load_rig(EXAMPLES / "rigs" / "clear.toml")
    d = design_mirrors(rig, search=False)
    assert d.ok, d.problems
    assert d.rig == rig  # the file holds exactly the designed extents
    return rig


@pytest.fixture(scope="session")
def reference():
    return ReferenceRig()


@pytest.fixture(scope="session")
def disc_video(tmp_path_factory):
    """A 3 s, 30 frames/s lossless (FFV1) simulated video of a disc moving in depth and sideways, through the
    default rig: (path, true depth per frame (mm), the rig, the disc scene, rig positions (N, 3) mm)."""
    from psvs.io.video import write_video
    from psvs.live.simulated import SimulatedSequence, disc_scene, ping_pong_positions
    rig = default_rig()
    scene = disc_scene(z_mm=760.0, radius_mm=30.0, x_mm=-20.0, y_mm=10.0)
    positions = ping_pong_positions(90, [24.0, -10.0, -120.0], 8)
    path = tmp_path_factory.mktemp("video") / "disc.avi"
    assert write_video(path, SimulatedSequence(scene, rig, positions, seed=3), fps=30.0) == 90
    return path, 760.0 - positions[:, 2], rig, scene, positions


@pytest.fixture(scope="session")
def wall_video(tmp_path_factory):
    """:func:`write_wall_video` through the default rig. Its first frame's dense map is made here once, so
    that a test's time limit on a live loop counts no compiling of the dense kernels (minutes on a fresh
    clone, on the first test of a worker that runs them)."""
    from psvs.live.dense import DenseSensor
    from psvs.live.source import VideoSource
    path, truth = write_wall_video(tmp_path_factory.mktemp("wall"), default_rig())
    with VideoSource(video=str(path)) as source:
        DenseSensor(default_rig()).step(source.read())
    return path, truth


@pytest.fixture(scope="session")
def hand_video(tmp_path_factory):
    """11 poses of the card through the misaligned build (640x480), held 3 frames each, one moving frame
    between them (2 renders over its exposure), every 4th pose settling slowly into place, the 6th partly
    out of the image."""
    return write_hand_video(tmp_path_factory.mktemp("hand"), hold_frames=3, move_frames=1, blur_samples=2,
                            out_every=6, settle_every=4)
