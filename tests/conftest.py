import atexit
import dataclasses
import hashlib
import math
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest

from psvs import default_rig
from psvs.io.params import load_rig
from psvs.optics.design import design_mirrors
from tests.reference_optics import ReferenceRig

#: fixtures every test file sees: the browser tests' Chromium page (tests/support/browser.py)
pytest_plugins = ["tests.support.browser"]

#: The session's own cache folder (psvs.dense.rig_cache): the tests never read or write the user's, and each
#: session starts empty. Set at import, before any test or command runs (subprocesses inherit it); removed
#: when the process ends (also when a script, not pytest, imports this module).
SESSION_CACHE = tempfile.mkdtemp(prefix="psvs-test-cache-")
os.environ["PSVS_CACHE_DIR"] = SESSION_CACHE
atexit.register(shutil.rmtree, SESSION_CACHE, ignore_errors=True)
#: A fresh clone's first dense command says that it compiles (psvs._compiled); the tests check commands'
#: stderr line by line, and which test compiles first is chance: the notice is off (tests/test_compiled.py on).
os.environ["PSVS_NO_COMPILE_NOTICE"] = "1"
#: The memory guard (psvs._memory) sees 8 GiB, whatever else the machine runs: a test's refusal or answer must
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


EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


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


def whole_field_points(rig, n_side=9, depths=(400.0, 600.0, 800.0, 1000.0, 1200.0)):
    """Points over the whole field seen by *both* views, at the given depths (mm), shape (N, 3)."""
    pts = []
    a_x, a_y = rig.camera.half_fov_rad
    for z in depths:
        half_w = (z - rig.virtual_z_mm) * math.tan(a_x) - rig.mirrors.baseline_mm / 2
        half_h = (z - rig.virtual_z_mm) * math.tan(a_y)
        gx, gy = np.meshgrid(np.linspace(-0.99, 0.99, n_side), np.linspace(-0.99, 0.99, n_side))
        pts.append(np.column_stack([gx.ravel() * half_w, gy.ravel() * half_h, np.full(gx.size, z)]))
    return np.concatenate(pts)


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


def read_mcap(path):
    """An MCAP file through the `mcap` reader (independent of psvs): ({topic: (schema name, message
    encoding)}, {topic: message count}, [(schema, channel, message)] in the file's order, so a test of rising
    time stamps tests the file)."""
    from mcap.reader import make_reader
    with Path(path).open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        topics = {c.topic: (summary.schemas[c.schema_id].name, c.message_encoding) for c in summary.channels.values()}
        counts = {summary.channels[k].topic: n for k, n in summary.statistics.channel_message_counts.items()}
        return topics, counts, list(reader.iter_messages(log_time_order=False))


WALL_MM = 700.0


def write_wall_video(folder, rig, frames: int = 6):
    """``frames`` frames (30/s, FFV1) of a grass-photo wall filling the view at 700 mm, the rig moving 0..-40 mm
    in depth over 3 positions, rendered through ``rig``: (path, true depth of every pixel per frame (mm))."""
    from psvs.io.video import write_video
    from psvs.live.simulated import SimulatedSequence, ping_pong_positions
    from psvs.simulate.builtin import _photo, regulated_light
    from psvs.simulate.scene import Scene
    scene = Scene((), regulated_light(WALL_MM), WALL_MM, _photo("grass", (1400.0, 1050.0)), "wall")
    positions = ping_pong_positions(frames, [0.0, 0.0, -40.0], 3)
    path = Path(folder) / "wall.avi"
    assert write_video(path, SimulatedSequence(scene, rig, positions, seed=5), fps=30.0) == frames
    return path, WALL_MM - positions[:, 2]


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


def kabsch(src: np.ndarray, dst: np.ndarray):
    """Rotation (3, 3) and translation (3,) minimising |R src + t - dst| (independent of psvs)."""
    cs, cd = src.mean(axis=0), dst.mean(axis=0)
    U, _, Vt = np.linalg.svd((src - cs).T @ (dst - cd))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    return R, cd - R @ cs


def reconstruction_errors(calibrated, true_rig, depths=(400.0, 600.0, 800.0, 1000.0, 1200.0), scale=1.0):
    """Triangulate the true correspondences of points over the whole common field (400-1200 mm) with a
    calibrated rig (exact model). Returns (3-D errors in frame C, mm; 3-D errors after the best rigid
    motion, mm; the points (N, 3)). Images cannot fix frame C's placement behind the mirrors completely
    (docs/calibration.md): the second number is the reconstruction's own accuracy. ``scale`` multiplies
    the reconstruction first (to take out a known scale error)."""
    from psvs.measure.triangulate import triangulate
    from psvs.optics.project import in_image, project_points
    pts = whole_field_points(default_rig(), n_side=9, depths=depths)
    left, okl = project_points(pts, true_rig, "left")
    right, okr = project_points(pts, true_rig, "right")
    seen = okl & okr & in_image(left, true_rig) & in_image(right, true_rig)
    got = scale * triangulate(left[seen], right[seen], calibrated, model="exact").points_mm
    raw = np.linalg.norm(got - pts[seen], axis=1)
    R, t = kabsch(got, pts[seen])
    aligned = np.linalg.norm(got @ R.T + t - pts[seen], axis=1)
    return raw, aligned, pts[seen]


#: The hand-held card of the capture tests (psvs card-views' default card).
HAND_CARD = (4, 6, 14.0, 7.0)


@dataclasses.dataclass(frozen=True)
class HandVideo:
    """A simulated hand-held video (FFV1): its path, the frames' plan (kind and true poses, frame C), the
    target file, the rig it was rendered through."""

    path: Path
    plan: list
    target: Path
    rig: object


def write_hand_video(folder, rig_name: str = "misaligned", holds: int = 11, seed: int = 1, card=HAND_CARD,
                     frames: int | None = None, shared: bool = False, **hand) -> HandVideo:
    """A hand-held card (psvs.calibrate.handheld) through a shipped rig: ``holds`` poses, the first ``frames``
    frames of the path (all by default), written to FOLDER/hand.avi with FOLDER/target.toml. ``shared``: the
    video rendered once for the session's processes (tests/support/shared_files.py), FOLDER/hand.avi a link
    to it."""
    from psvs.calibrate.handheld import HandParams, hand_path, render_hand_video
    from psvs.calibrate.target_file import dumps_target
    from psvs.io.video import write_video
    from psvs.simulate.textures import CircleGrid
    from tests.support.shared_files import shared_file
    folder = Path(folder)
    rig, grid = load_rig(rig_name), CircleGrid(*card)
    plan = hand_path(rig, grid, holds, seed=seed, hand=HandParams(**hand))[:frames]
    (folder / "target.toml").write_text(dumps_target(grid))
    path = folder / "hand.avi"

    def render(to: Path):
        assert write_video(to, render_hand_video(rig, grid, plan, seed=seed), fps=30.0) == len(plan)

    if shared:
        key = "_".join(str(x) for x in (rig_name, holds, seed, card, frames, sorted(hand.items())))
        name = "hand-" + hashlib.sha256(key.encode()).hexdigest()[:16] + ".avi"
        path.symlink_to(shared_file(name, render))
    else:
        render(path)
    return HandVideo(path, plan, folder / "target.toml", rig)


@pytest.fixture(scope="session")
def hand_video(tmp_path_factory):
    """11 poses of the card through the misaligned build (640x480), held 3 frames each, one moving frame
    between them (2 renders over its exposure), every 4th pose settling slowly into place, the 6th partly
    out of the image."""
    return write_hand_video(tmp_path_factory.mktemp("hand"), hold_frames=3, move_frames=1, blur_samples=2,
                            out_every=6, settle_every=4)
