"""Arm, hand-eye, seam model and seam-point fit against planted truth (fast)."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from psvs.optics.rig import default_rig
from psvs.optics.window import roi_rig
from psvs.robot.arm import Arm, ArmLimits
from psvs.robot.controller import TrackConfig
from psvs.robot.handeye import calibrate_hand_eye, rigid_fit
from psvs.robot.mounting import HOME_Q, tool2flange, tool_pose
from psvs.robot.seam import fit_seam_point
from psvs.robot.seam_model import SeamPath


def _T(rotvec, t):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = Rotation.from_rotvec(rotvec).as_matrix(), t
    return T


def test_ik_reaches_a_torch_pose_and_fk_agrees():
    arm = Arm(HOME_Q)
    tool = tool_pose([560.0, -40.0, 20.0], [0.3, 1.0, 0.0])
    q = arm.ikine(tool @ np.linalg.inv(tool2flange()))
    got = arm.fkine(q) @ tool2flange()
    assert np.allclose(got, tool, atol=1e-6)
    assert arm.within_limits(q)


def test_ik_rejects_an_unreachable_pose():
    arm = Arm(HOME_Q)
    with pytest.raises(ValueError, match="unreachable|joint range"):
        arm.ikine(tool_pose([3000.0, 0.0, 0.0], [1.0, 0.0, 0.0]))


def test_servo_never_jumps_and_respects_speed_and_acceleration():
    """A set-point 1 rad away: the servo moves at most qd_max * T per cycle, accelerations within qdd_max."""
    lim = ArmLimits()
    arm = Arm(HOME_Q, lim)
    target = HOME_Q + 1.0
    prev = arm.q.copy()
    for _ in range(10):
        step = arm.servo(target, 0.04)
        assert np.all(np.abs(step.q - prev) <= np.asarray(lim.qd_max) * 0.04 + 1e-12)
        assert np.all(step.qdd_peak <= np.asarray(lim.qdd_max) + 1e-9)
        prev = step.q
    assert step.limited


def test_servo_follows_a_slow_ramp_exactly():
    arm = Arm(HOME_Q)
    for k in range(1, 30):
        arm.servo(HOME_Q + 0.001 * k, 0.04)
    assert np.allclose(arm.q, HOME_Q + 0.029, atol=2e-4)


def test_servo_brakes_before_the_joint_range():
    arm = Arm(HOME_Q)
    beyond = HOME_Q.copy()
    beyond[0] = arm.qlim[1, 0] + 1.0
    for _ in range(200):
        arm.servo(beyond, 0.04)
    assert arm.q[0] <= arm.qlim[1, 0] + 1e-9


def test_arm_limits_are_checked():
    with pytest.raises(ValueError, match="qd_max must be six positive"):
        ArmLimits(qd_max=(1.0, 1.0))


def test_hand_eye_recovers_a_planted_mounting():
    """AX = XB with exact flange poses and target2cam = inv(F X)^-1 target2base: X back to 1e-6."""
    rng = np.random.default_rng(0)
    X = _T([0.01, -0.02, 1.5], [40.0, 5.0, -280.0])
    target2base = _T([np.pi, 0, 0], [550.0, 0.0, 0.0])
    F = [_T(rng.uniform(-0.4, 0.4, 3) + [np.pi, 0, 0], rng.uniform(-50, 50, 3) + [500, 0, 300]) for _ in range(8)]
    t2c = [np.linalg.inv(f @ X) @ target2base for f in F]
    assert np.allclose(calibrate_hand_eye(F, t2c), X, atol=1e-6)
    with pytest.raises(ValueError, match=">= 3 paired views"):
        calibrate_hand_eye(F[:2], t2c[:2])


def test_hand_eye_agrees_with_opencv_park_on_noisy_poses():
    """With noisy camera poses (0.5 mrad, 0.2 mm) the Park-Martin solution stays within 2 mrad / 1 mm of
    the planted mounting, and within 1 mrad / 0.5 mm of OpenCV 4's CALIB_HAND_EYE_PARK (an independent
    implementation; OpenCV 5's Python wheels dropped calibrateHandEye, where only the planted truth is
    checked)."""
    import cv2
    rng = np.random.default_rng(7)
    X = _T([0.02, 0.01, -1.2], [-35.0, 12.0, -260.0])
    target2base = _T([np.pi, 0.05, 0], [600.0, 40.0, 0.0])
    F = [_T(rng.uniform(-0.5, 0.5, 3) + [np.pi, 0, 0], rng.uniform(-60, 60, 3) + [520, 0, 320]) for _ in range(12)]
    t2c = [_T(rng.normal(0, 5e-4, 3), rng.normal(0, 0.2, 3)) @ np.linalg.inv(f @ X) @ target2base for f in F]
    got = calibrate_hand_eye(F, t2c)

    def angle(Ra, Rb):
        return np.arccos(np.clip((np.trace(Ra.T @ Rb) - 1) / 2, -1, 1))

    assert angle(got[:3, :3], X[:3, :3]) < 2e-3 and np.linalg.norm(got[:3, 3] - X[:3, 3]) < 1.0
    if hasattr(cv2, "calibrateHandEye"):
        R, t = cv2.calibrateHandEye([f[:3, :3] for f in F], [f[:3, 3] for f in F], [c[:3, :3] for c in t2c],
                                    [c[:3, 3] for c in t2c], method=cv2.CALIB_HAND_EYE_PARK)
        assert angle(got[:3, :3], R) < 1e-3 and np.linalg.norm(got[:3, 3] - np.ravel(t)) < 0.5


def test_hand_eye_refuses_poses_turning_about_one_axis():
    """Rotations about one axis only leave X's rotation about that axis unobservable."""
    X = _T([0.01, -0.02, 1.5], [40.0, 5.0, -280.0])
    target2base = _T([np.pi, 0, 0], [550.0, 0.0, 0.0])
    F = [_T([0.0, 0.0, a], [500.0, 10 * a, 300.0]) for a in (0.0, 0.2, 0.4, 0.6)]
    t2c = [np.linalg.inv(f @ X) @ target2base for f in F]
    with pytest.raises(ValueError, match="turn about at least two axes"):
        calibrate_hand_eye(F, t2c)


def test_rigid_fit_recovers_a_transform():
    rng = np.random.default_rng(1)
    src = rng.normal(size=(10, 3)) * 30
    T = _T([0.2, -0.1, 0.3], [1.0, 2.0, 3.0])
    got, rms = rigid_fit(src, src @ T[:3, :3].T + T[:3, 3])
    assert np.allclose(got, T, atol=1e-9) and rms < 1e-9


def _circle(s, R=150.0):
    return np.column_stack([R * np.sin(s / R), R - R * np.cos(s / R), 0.05 * s])


def test_seam_path_follows_a_noisy_circle_and_bridges_along_the_tangent():
    rng = np.random.default_rng(2)
    s_true = np.arange(0.0, 60.0, 0.4)
    pts = _circle(s_true) + rng.normal(0, 0.03, (len(s_true), 3))
    path = SeamPath(pts[0], [1.0, 0.0, 0.0])
    for p, s in zip(pts[1:], s_true[1:], strict=True):
        t = _circle(np.array([s + 0.01]))[0] - _circle(np.array([s]))[0]
        path.add(p, t / np.linalg.norm(t))
    path.fit(20.0)
    dense = _circle(np.arange(0.0, 60.0, 0.005))
    # distance to the curve (the arc length itself may drift along it), at the last knot too: the fit keeps
    # the seam's curvature where the knots end (a smoothing spline's natural end straightens it)
    for s in (25.0, 40.0, 50.0, path.s_end - 2.0, path.s_end):
        assert np.min(np.linalg.norm(dense - path.position(s), axis=1)) < 0.04   # noise 0.03 per knot
    assert abs(path.s_end - 59.6) < 0.5
    end, t_end = path.position(path.s_end), path.tangent(path.s_end)
    assert np.allclose(path.position(path.s_end + 10.0), end + 10.0 * t_end, atol=1e-9)
    assert not path.add(pts[-1], t_end)   # not ahead of the last knot


@pytest.mark.parametrize("seed", [2, 3, 4])
def test_seam_path_bridges_a_gap_in_its_knots(seed):
    """Knots (noise 0.03 mm) on a circle of radius 150 mm with a 14 mm stretch unseen (a filled gap and the
    groove ends beside it): across the gap and near its edges the model stays within 0.05 mm of the curve
    (it fits the knots on both sides, it does not extrapolate the last ones before the gap)."""
    rng = np.random.default_rng(seed)
    s_true = np.arange(0.0, 80.0, 0.4)
    s_true = s_true[(s_true < 30.0) | (s_true > 44.0)]
    pts = _circle(s_true) + rng.normal(0, 0.03, (len(s_true), 3))
    path = SeamPath(pts[0], [1.0, 0.0, 0.0])
    for p, s in zip(pts[1:], s_true[1:], strict=True):
        t = _circle(np.array([s + 0.01]))[0] - _circle(np.array([s]))[0]
        path.add(p, t / np.linalg.norm(t))
    path.fit(25.0)
    dense = _circle(np.arange(0.0, 80.0, 0.005))
    for s in np.arange(26.0, 48.0, 0.5):
        assert np.min(np.linalg.norm(dense - path.position(s), axis=1)) < 0.05, s


def test_fit_seam_point_on_a_curved_groove():
    """Edges of a groove of half-width 6 mm around a circle of radius 150 mm (z up): the root is the centre
    line, depth below; quadratic fits leave no chord bias."""
    s = np.linspace(-5, 5, 30)
    c = _circle(s + 50.0)
    t = np.gradient(c, axis=0)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    n = np.cross([0, 0, 1.0], t)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    sp = fit_seam_point(c + 6 * n, c - 6 * n, 3.0, np.array([0, 0, 1.0]))
    mid = _circle(np.array([50.0]))[0] - [0, 0, 3.0]
    assert np.linalg.norm(sp.point_mm - mid) < 0.02
    assert abs(sp.width_mm - 12.0) < 0.01


def test_roi_rig_keeps_the_optics_and_checks_rows():
    rig, v0 = roi_rig(default_rig(), 32)
    assert rig.camera.image_size_px == (640, 32) and v0 == 224
    assert rig.camera.principal_point_px[1] == pytest.approx(239.5 - 224)
    with pytest.raises(ValueError, match="roi_rows must be an integer"):
        roi_rig(default_rig(), 4)
    # the ideal rig's window does not grow, whatever the range
    assert roi_rig(default_rig(), 32, span_mm=(220.0, 420.0))[0].camera.image_size_px == (640, 32)


@pytest.mark.parametrize("rows, span", [(32, (220.0, 420.0)), (24, (450.0, 900.0))])
def test_roi_window_on_a_build_holds_the_twins(rows, span):
    """On a build the window grows so that a point the left view sees on its central ``rows`` rows has its
    right-view twin inside the window too: checked on random scene points projected into both views
    (project_points, not the traced rays roi_rig uses)."""
    from psvs.io.params import load_rig
    from psvs.optics.project import project_points
    build = load_rig("misaligned")
    full_h = build.camera.image_size_px[1]
    band0 = int(round(build.camera.principal_point_px[1] - (rows - 1) / 2))
    roi, v0 = roi_rig(build, rows, span_mm=span)
    h = roi.camera.image_size_px[1]
    assert rows + 4 < h <= full_h and 0 <= v0 <= band0 <= band0 + rows <= v0 + h
    # the optics unchanged: a pixel's ray is the same in the window (rows shifted by v0)
    rng = np.random.default_rng(3)
    z = rng.uniform(*span, 4000)
    pts = np.column_stack([rng.uniform(-0.4, 0.4, 4000) * z, rng.uniform(-0.1, 0.1, 4000) * z, z])
    left, ok_l = project_points(pts, build, "left")
    right, ok_r = project_points(pts, build, "right")
    inband = ok_l & ok_r & (left[:, 1] >= band0) & (left[:, 1] <= band0 + rows - 1) & \
        (left[:, 0] >= 0) & (left[:, 0] <= build.camera.image_size_px[0] - 1)
    assert inband.sum() > 50
    assert np.all(right[inband, 1] >= v0 - 0.5) and np.all(right[inband, 1] <= v0 + h - 0.5)
    # the twins really are rows apart on this build (the reason for the taller window)
    assert np.abs(right[inband, 1] - left[inband, 1]).max() > 5.0
    roi_left, _ = project_points(pts[inband], roi, "left")
    assert np.allclose(roi_left[:, 1], left[inband, 1] - v0, atol=1e-6)


def test_groove_edges_drop_the_end_outline():
    """Where the groove ends in the window its outline closes the band (the V's end, oblique in the image):
    the outline's pixels go; each edge keeps its own, also on rows where the other edge has already ended
    (edge a runs on to row 29, edge b ends at row 21 and the outline runs from there toward edge a)."""
    from psvs.robot.sensor import groove_edges
    v = np.arange(30.0)
    ua = 300.0 + 0.1 * v + np.random.default_rng(1).choice([-0.5, 0.0, 0.5], 30)
    ub = 340.0 + 0.1 * v
    ub[22:] = 340.0 + 0.1 * v[22:] - 4.0 * (v[22:] - 21)   # rows 22..29: the outline, not edge b
    pa, pb = np.column_stack([ua, v]), np.column_stack([ub, v])
    xa = np.column_stack([v, np.zeros(30), np.zeros(30)])
    xb = np.column_stack([v, np.ones(30), np.zeros(30)])
    a, b = groove_edges(((pa, xa), (pb, xb)), 20.0)
    assert a[:, 0].tolist() == list(range(30))          # edge a whole, past edge b's end
    assert b[:, 0].tolist() == list(range(22))          # edge b without the outline
    # an outline pixel on edge a's side (the corner where the outline meets it, 5 px off) goes too
    pa2 = np.vstack([pa, [ua[10] + 5.0, 10.0]])
    xa2 = np.vstack([xa, [99.0, 0.0, 0.0]])
    a2, _ = groove_edges(((pa2, xa2), (pb, xb)), 20.0)
    assert 99.0 not in a2[:, 0]


def test_track_config_checks():
    with pytest.raises(ValueError, match="speed_mm_s must be a number > 0"):
        TrackConfig(speed_mm_s=-1.0)
    with pytest.raises(ValueError, match="rate_hz must be in"):
        TrackConfig(rate_hz=1000.0)
    with pytest.raises(ValueError, match="roi_rows must be an integer >= 8"):
        TrackConfig(roi_rows=4)
    with pytest.raises(ValueError, match="bridge_mm must be in"):
        TrackConfig(bridge_mm=50.0)


def test_hand_eye_from_views_needs_three_readable_views():
    """Blank images: no grid in any view; the error names how many were read and why the first was not."""
    from psvs.optics.rig import default_rig
    from psvs.robot.handeye import calibrate_from_views
    from psvs.simulate.textures import CircleGrid
    blank = [np.full((480, 640), 128, np.uint8)] * 4
    with pytest.raises(ValueError, match=r"needs >= 3 readable views, 0 of 4 read; view 0: found 0 disc"):
        calibrate_from_views(blank, [np.eye(4)] * 4, default_rig(), CircleGrid(4, 5, 15.0, 7.0))
