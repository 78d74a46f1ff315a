import math

import numpy as np
import pytest

from psvs.optics.mirror_length import (
    ab_eq1,
    bc_eq5,
    mirror_length_eq6,
    mirror_length_eq7,
    mirror_length_eq8,
    segments_eq2_4,
)
from psvs.optics.surfaces import Plane, intersect

RNG = np.random.default_rng(0)
CASES = [(float(RNG.uniform(5, 200)), float(RNG.uniform(0.05, 0.6))) for _ in range(20)]


@pytest.mark.parametrize("ob, a", CASES)
def test_eq7_at_45_deg(ob, a):
    assert mirror_length_eq6(ob, a, math.pi / 4) == pytest.approx(mirror_length_eq7(ob, a), rel=1e-12)
    assert mirror_length_eq7(ob, a) == pytest.approx(math.sqrt(2) * ob * math.tan(2 * a), rel=1e-12)


@pytest.mark.parametrize("ob, a", CASES)
def test_eq8_at_90_deg(ob, a):
    assert mirror_length_eq6(ob, a, math.pi / 2) == pytest.approx(mirror_length_eq8(ob, a), rel=1e-12)
    assert mirror_length_eq8(ob, a) == pytest.approx(2 * ob * math.tan(a), rel=1e-12)


@pytest.mark.parametrize("seed", range(15))
def test_eq6_against_direct_ray_mirror_intersection(seed):
    """Intersect the two edge rays (+-a) from O with a mirror line through B = (0, 0, OB) at angle w."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(0.05, 0.5)
    w = rng.uniform(a + 0.05, math.pi / 2)
    ob = rng.uniform(5, 200)
    s_axis = np.array([math.sin(w), 0.0, math.cos(w)])
    normal = np.array([math.cos(w), 0.0, -math.sin(w)])
    plane = Plane("m", np.array([0.0, 0.0, ob]), normal, s_axis)
    dirs = np.array([[math.sin(a), 0, math.cos(a)], [-math.sin(a), 0, math.cos(a)]])
    t, hits, ahead = intersect(np.zeros((2, 3)), dirs, plane)
    assert ahead.all()
    s = plane.local(hits)[:, 0]
    assert s[0] - s[1] == pytest.approx(float(mirror_length_eq6(ob, a, w)), rel=1e-12)
    assert s[0] == pytest.approx(float(ab_eq1(ob, a, w)), rel=1e-12)      # far side
    assert -s[1] == pytest.approx(float(bc_eq5(ob, a, w)), rel=1e-12)     # near side


def test_eq2_4_consistent_with_eq5():
    ob, a, w = 40.0, 0.3, 0.9
    cd, bc, od, db = segments_eq2_4(ob, a, w)
    assert bc == pytest.approx(float(bc_eq5(ob, a, w)), rel=1e-12)
    assert od + db == pytest.approx(ob, rel=1e-12)
    assert cd == pytest.approx(od * math.tan(a), rel=1e-12)


def test_errors():
    with pytest.raises(ValueError, match="omega_1 must exceed the half field angle a"):
        mirror_length_eq6(10.0, 0.5, 0.4)
    with pytest.raises(ValueError, match="OB must be > 0 mm"):
        mirror_length_eq6(-1.0, 0.2, 0.8)
    with pytest.raises(ValueError, match=r"half field angle a must be in \(0, pi/2\)"):
        mirror_length_eq7(10.0, 0.0)
