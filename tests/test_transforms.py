"""psvs.transforms against independent derivations: scipy's Rotation for the rotation-vector formula, and the
rigid transforms' algebra (inverse, chaining) on random cases."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from psvs.transforms import concat, invert_transform, matrix_from_rotvec, transform_from_rotvec, transform_points


@pytest.mark.parametrize("seed", range(5))
def test_rotation_vector_matches_scipy(seed):
    """Random rotation vectors of every size, from 1e-9 rad (the series) to pi: within 1e-14 of scipy."""
    rng = np.random.default_rng(seed)
    for angle in (1e-9, 1e-4, 0.003, 0.5, 2.0, np.pi):
        axis = rng.normal(size=3)
        v = angle * axis / np.linalg.norm(axis)
        np.testing.assert_allclose(matrix_from_rotvec(v), Rotation.from_rotvec(v).as_matrix(), atol=1e-14)
    np.testing.assert_array_equal(matrix_from_rotvec(np.zeros(3)), np.eye(3))


def test_a_transform_from_a_rotation_vector_inverts_and_chains():
    rng = np.random.default_rng(7)
    A2B = transform_from_rotvec(rng.normal(size=3), rng.normal(size=3) * 100)
    pts = rng.normal(size=(5, 3)) * 50
    np.testing.assert_allclose(transform_points(invert_transform(A2B), transform_points(A2B, pts)), pts, atol=1e-10)
    np.testing.assert_allclose(concat(A2B, invert_transform(A2B)), np.eye(4), atol=1e-12)
    with pytest.raises(ValueError, match=r"rotvec must have shape \(3,\), got \(2,\)"):
        matrix_from_rotvec([0.1, 0.2])
