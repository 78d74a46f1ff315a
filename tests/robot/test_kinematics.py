"""psvs.robot.kinematics against roboticstoolbox-python's Puma560 (Corke), the independent reference."""
import numpy as np
import pytest
import roboticstoolbox as rtb

from psvs.robot.arm import Arm
from psvs.robot.kinematics import PUMA560, ikine_lm, rotation_error
from psvs.robot.mounting import HOME_Q

TOOLBOX = rtb.models.DH.Puma560()


def _toolbox_fkine_mm(q):
    T = np.array(TOOLBOX.fkine(q).A)
    T[:3, 3] *= 1000.0
    return T


def test_the_dh_table_is_the_toolbox_puma560_in_mm():
    for i, link in enumerate(TOOLBOX.links):
        assert PUMA560.d[i] == pytest.approx(link.d * 1000.0, abs=1e-9)
        assert PUMA560.a[i] == pytest.approx(link.a * 1000.0, abs=1e-9)
        assert PUMA560.alpha[i] == pytest.approx(link.alpha, abs=1e-15)
        assert PUMA560.offset[i] == pytest.approx(link.offset, abs=1e-15)
        assert not link.mdh and not link.isflip
    np.testing.assert_allclose(PUMA560.qlim, TOOLBOX.qlim, atol=1e-12)
    np.testing.assert_array_equal(TOOLBOX.base.A, np.eye(4))
    np.testing.assert_array_equal(TOOLBOX.tool.A, np.eye(4))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_forward_kinematics_and_jacobian_match_the_toolbox(seed):
    rng = np.random.default_rng(seed)
    for _ in range(30):
        q = rng.uniform(PUMA560.qlim[0], PUMA560.qlim[1])
        np.testing.assert_allclose(PUMA560.fkine(q), _toolbox_fkine_mm(q), atol=1e-9)   # mm
        J = np.array(TOOLBOX.jacob0(q))
        J[:3] *= 1000.0
        np.testing.assert_allclose(PUMA560.jacobian(q), J, atol=1e-9)


def test_jacobian_is_the_derivative_of_the_pose():
    q = np.radians([10.0, 30.0, -100.0, 20.0, 40.0, -60.0])
    J = PUMA560.jacobian(q)
    h = 1e-6
    T0 = PUMA560.fkine(q)
    for i in range(6):
        dq = np.zeros(6)
        dq[i] = h
        T1 = PUMA560.fkine(q + dq)
        np.testing.assert_allclose((T1[:3, 3] - T0[:3, 3]) / h, J[:3, i], atol=1e-3)     # mm/rad
        np.testing.assert_allclose(rotation_error(T1[:3, :3], T0[:3, :3]) / h, J[3:, i], atol=1e-6)


@pytest.mark.parametrize("angle", [0.0, 1e-7, 0.3, 2.0, np.pi - 1e-9, np.pi])
def test_rotation_error_is_the_rotation_vector(angle):
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    R = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K        # Rodrigues
    base = _toolbox_fkine_mm(np.radians([5.0, 20.0, -90.0, 10.0, 30.0, 0.0]))[:3, :3]
    v = rotation_error(R @ base, base)
    if angle < np.pi - 1e-6:
        np.testing.assert_allclose(v, axis * angle, atol=1e-12)
    else:     # a half turn: either sign of the axis
        assert min(np.linalg.norm(v - axis * np.pi), np.linalg.norm(v + axis * np.pi)) < 1e-6


@pytest.mark.parametrize("seed", [3, 4])
def test_inverse_kinematics_recovers_planted_joints_as_the_toolbox_does(seed):
    rng = np.random.default_rng(seed)
    tested = 0
    while tested < 20:
        q = rng.uniform(PUMA560.qlim[0] + 0.3, PUMA560.qlim[1] - 0.3)
        J = PUMA560.jacobian(q) * np.r_[np.full(3, 1e-3), np.ones(3)][:, None]     # m/rad and rad/rad
        if np.linalg.svd(J, compute_uv=False)[-1] < 0.05:
            continue       # near a singularity (wrist, elbow, shoulder): neighbouring solutions
        tested += 1
        q0 = q + rng.uniform(-0.1, 0.1, 6)
        target = PUMA560.fkine(q)
        sol = ikine_lm(PUMA560, target, q0)
        assert sol.success and sol.position_error_mm <= 1e-7 and sol.rotation_error_rad <= 1e-10
        np.testing.assert_allclose(sol.q, q, atol=1e-7)        # the solution nearest q0: the planted one
        ref = TOOLBOX.ikine_LM(TOOLBOX.fkine(q), q0=q0, tol=1e-14, ilimit=200, slimit=1)
        if ref.success:    # the toolbox from the same start lands on the same joints
            np.testing.assert_allclose(sol.q, ref.q, atol=1e-5)


def test_unreachable_pose_fails_and_the_arm_says_so():
    target = np.eye(4)
    target[:3, 3] = [3000.0, 0.0, 500.0]           # 3 m away: beyond the PUMA's reach (~0.9 m)
    sol = ikine_lm(PUMA560, target, HOME_Q)
    assert not sol.success and sol.position_error_mm > 1000.0
    with pytest.raises(ValueError, match="pose unreachable"):
        Arm(HOME_Q).ikine(target)
    with pytest.raises(ValueError, match="finite 4x4"):
        ikine_lm(PUMA560, np.full((4, 4), np.nan), HOME_Q)
    with pytest.raises(ValueError, match="6 joint angles"):
        PUMA560.fkine(np.zeros(5))
