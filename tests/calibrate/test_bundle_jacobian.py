"""The bundle adjustment's Jacobian (psvs.calibrate.bundle) against the plain central difference of its own
residual function, column by column: the lens's columns are taken without tracing a ray and the poses' through
the projection's derivative by the point, so each shortcut is checked against the derivative it stands for, on
drawn rigs (a lens with distortion, pixels not square, a plate, mirrors turned) and drawn card poses."""
import numpy as np
import pytest

from psvs.calibrate.bundle import (
    DIFF_STEP,
    POSE_STEP,
    RIG_PARAMS,
    SWEEP_PARAMS,
    BundleProblem,
    GridView,
    SweepView,
    initial_grid_pose,
    initial_sweep,
    rig_vector,
)
from psvs.calibrate.synthetic import random_poses
from psvs.io.params import load_rig
from psvs.optics.project import project_points
from psvs.optics.rig import MirrorError
from psvs.simulate.textures import CircleGrid
from psvs.targets.target_points import target_points_mm
from tests.support.geometry import EXAMPLES

CARD = CircleGrid(4, 6, 14.0, 7.0)


def drawn_rig(seed: int):
    """The misaligned build with its lens, pixel aspect and mirrors drawn about their values."""
    rng = np.random.default_rng(seed)
    rig = load_rig(EXAMPLES / "rigs" / "misaligned.toml")
    pitch = rig.camera.pixel_pitch_mm[0]
    rig = rig.replace(distortion=(rng.uniform(-0.3, 0.1), rng.uniform(-0.2, 0.4), rng.uniform(-2e-3, 2e-3),
                                  rng.uniform(-2e-3, 2e-3), rng.uniform(-0.3, 0.3)),
                      pixel_pitch_mm=(pitch, pitch * rng.uniform(0.98, 1.02)))
    errors = {m: MirrorError(tuple(rng.normal(0, 2e-3, 2)), rng.normal(0, 0.1)) for m in ("m1", "m2", "m3", "m4")}
    return rig.with_errors(errors)


def views(rig, n: int, seed: int) -> list[GridView]:
    """``n`` card views through ``rig``, their centres projected exactly and moved by 0.05 px of noise."""
    rng = np.random.default_rng(seed)
    local = target_points_mm(CARD)
    local = np.column_stack([local, np.zeros(len(local))])
    out = []
    for k, pose in enumerate(random_poses(rig, CARD, n, seed=seed)):
        pts = pose.to_world(local)
        left, right = (project_points(pts, rig, view)[0] + rng.normal(0, 0.05, (len(pts), 2))
                       for view in ("left", "right"))
        out.append(GridView(f"v{k}", local, left, right))
    return out


def central_difference(prob: BundleProblem, x: np.ndarray) -> np.ndarray:
    """d residuals / d x by central differences of ``prob.residuals``, every projection started afresh."""
    names = prob.names + ["pose"] * (len(x) - prob.n_rig)
    steps = [DIFF_STEP[p] for p in prob.names] + [POSE_STEP[q % 6] for q in range(len(x) - prob.n_rig)]
    assert len(steps) == len(names)
    J = np.empty((len(prob.residuals(x)), len(x)))
    for k, h in enumerate(steps):
        dx = np.zeros(len(x))
        dx[k] = h
        J[:, k] = (prob.residuals(x + dx) - prob.residuals(x - dx)) / (2 * h)
    return J


@pytest.mark.parametrize("seed", [1, 2])
def test_each_column_is_the_residuals_derivative(seed):
    """Every column (rig, lens and pose) within 1e-5 of its largest entry of the central difference (the
    columns the shortcuts give, the lens's and the poses', as the others)."""
    truth = drawn_rig(seed)
    grids = views(truth, 4, seed)
    start = load_rig(EXAMPLES / "rigs" / "misaligned.toml")
    prob = BundleProblem(grids, [], np.zeros((0, 3)), start, ())
    assert prob.names == list(RIG_PARAMS)
    # a point near the solution: the true rig's values, the poses a little off the truth
    x = np.concatenate([rig_vector(truth)] + [initial_grid_pose(g, truth) for g in grids])
    J = prob.jacobian(x)
    ref = central_difference(prob, x)
    scale = np.max(np.abs(ref), axis=0)
    assert np.all(scale > 0)
    err = np.max(np.abs(J - ref), axis=0) / scale
    worst = int(np.argmax(err))
    assert err[worst] <= 1e-5, (worst, (prob.names + ["pose"] * 99)[worst], err[worst])


def test_a_sweep_without_grids_keeps_its_columns():
    """With a robot sweep alone (no pose columns), the sweep's columns too are the residuals' derivative."""
    rig = drawn_rig(3)
    local = np.column_stack([np.linspace(-20.0, 20.0, 5), np.zeros(5), np.zeros(5)])
    sweeps = []
    for k, z in enumerate(np.linspace(450.0, 900.0, 6)):
        pts = local + [0.0, 0.0, z]
        sweeps.append(SweepView(f"s{k}", z, project_points(pts, rig, "left")[0], project_points(pts, rig, "right")[0]))
    prob = BundleProblem([], sweeps, local, rig, ("pixel_aspect", "k2", "p1", "p2", "k3"))
    x = np.concatenate([rig_vector(rig)[prob.free], initial_sweep(sweeps, local, rig)])
    J = prob.jacobian(x)
    steps = [DIFF_STEP[p] for p in prob.names + list(SWEEP_PARAMS)]
    for k, h in enumerate(steps):
        dx = np.zeros(len(x))
        dx[k] = h
        ref = (prob.residuals(x + dx) - prob.residuals(x - dx)) / (2 * h)
        assert np.max(np.abs(J[:, k] - ref)) <= 1e-5 * max(np.max(np.abs(ref)), 1e-9), k


def test_grids_with_a_sweep_and_a_point_no_view_sees():
    """Two card views (one holding a point 3 m to the side, which neither view reaches: its rows a constant
    residual, zero in every column) and a robot sweep: every column the residuals' central difference."""
    rig = drawn_rig(4)
    grids = views(rig, 2, 4)
    far = np.array([[3000.0, 0.0, 0.0]])
    g = grids[0]
    grids[0] = GridView(g.name, np.vstack([g.object_mm, far]), np.vstack([g.left, [[10.0, 10.0]]]),
                        np.vstack([g.right, [[20.0, 10.0]]]))
    local = np.column_stack([np.linspace(-20.0, 20.0, 5), np.zeros(5), np.zeros(5)])
    sweeps = []
    for k, z in enumerate(np.linspace(450.0, 900.0, 3)):
        pts = local + [0.0, 0.0, z]
        sweeps.append(SweepView(f"s{k}", z, project_points(pts, rig, "left")[0], project_points(pts, rig, "right")[0]))
    prob = BundleProblem(grids, sweeps, local, rig, ("k2", "p1", "p2", "k3"))
    x = np.concatenate([rig_vector(rig)[prob.free], initial_sweep(sweeps, local, rig)]
                       + [initial_grid_pose(g, rig) for g in grids])
    r0 = prob.residuals(x)
    assert np.count_nonzero(np.abs(r0[:4 * prob.n_points]) == 100.0) == 4        # the far point's 4 rows: missed
    J = prob.jacobian(x)
    steps = ([DIFF_STEP[p] for p in prob.names + list(SWEEP_PARAMS)]
             + [POSE_STEP[q % 6] for q in range(len(x) - prob.n_rig - len(SWEEP_PARAMS))])
    for k, h in enumerate(steps):
        dx = np.zeros(len(x))
        dx[k] = h
        ref = (prob.residuals(x + dx) - prob.residuals(x - dx)) / (2 * h)
        assert np.max(np.abs(J[:, k] - ref)) <= 1e-5 * max(np.max(np.abs(ref)), 1e-9), k


def _edge_x(rig, y: float, z: float, view: str) -> float:
    """The X (mm) at (., y, z) where ``view`` stops seeing a point (a finite mirror vignettes it), to 1e-6 mm:
    a point there is seen, one 1e-5 mm further out is not."""
    seen = lambda x: bool(project_points([[x, y, z]], rig, view)[1][0])  # noqa: E731
    inside, outside = 0.0, 50.0
    while seen(outside):
        inside, outside = outside, outside * 2.0
    while outside - inside > 1e-6:
        mid = 0.5 * (inside + outside)
        inside, outside = (mid, outside) if seen(mid) else (inside, mid)
    return inside


@pytest.mark.parametrize("view", ["left", "right"])
def test_a_point_the_step_takes_out_of_the_field_gives_no_derivative(view):
    """A sweep point at the edge of one view's field (a mirror's rim), within the sweep's X step of it: stepped,
    its rows would
    read the miss's constant residual; the columns are 0 there (not (miss - residual) / step, 1e6 px/mm) and
    the central difference elsewhere."""
    rig = load_rig(EXAMPLES / "rigs" / "clear.toml")       # mirrors of finite size: a field with an edge
    z = 600.0
    x_edge = _edge_x(rig, 0.0, z, view)
    step = DIFF_STEP["x0_mm"]
    local = np.array([[-20.0, 0.0, 0.0], [0.0, 0.0, 0.0], [20.0, 0.0, 0.0], [x_edge - 0.4 * step, 0.0, 0.0]])
    sweeps = []
    for k, zz in enumerate((z, z + 50.0, z + 100.0)):
        pts = local + [0.0, 0.0, zz]
        sweeps.append(SweepView(f"s{k}", zz, project_points(pts, rig, "left")[0], project_points(pts, rig, "right")[0]))
    prob = BundleProblem([], sweeps, local, rig, ("pixel_aspect", "k2", "p1", "p2", "k3"))
    x = np.concatenate([rig_vector(rig)[prob.free], initial_sweep(sweeps, local, rig)])
    x[prob.n_rig:] = [0.0, 0.0, 0.0, 0.0, 0.0]          # the sweep as planted: the edge point seen, just
    k = prob.n_rig + SWEEP_PARAMS.index("x0_mm")
    dx = np.zeros(len(x))
    dx[k] = step
    r0, r1 = prob.residuals(x), prob.residuals(x + dx)
    rows = 4 * prob.n_points
    flipped = np.flatnonzero((np.abs(r1[:rows]) == 100.0) != (np.abs(r0[:rows]) == 100.0))
    assert len(flipped) == 2, "the edge point, in one view, leaves the field under the step"
    J = prob.jacobian(x)
    assert np.all(J[flipped, k] == 0.0)
    assert np.max(np.abs(J[:rows])) < 1e5     # no (miss - residual) / step anywhere (100 px / 1e-4 mm: 1e6)
    kept = np.setdiff1d(np.arange(rows), flipped)
    ref = (prob.residuals(x + dx) - prob.residuals(x - dx)) / (2 * step)
    assert np.max(np.abs(J[kept, k] - ref[kept])) <= 1e-5 * np.max(np.abs(ref[kept]))
