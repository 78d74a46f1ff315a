"""The wide sweep of rigs drawn as users' cameras would be (issue 40, item 2; marked slow, CI runs it): the
draws and criteria of tests/dense/test_sweep.py on larger sensors."""
import pytest

from tests.support.sweep_scenes import LARGE, MID, MODES, SCENES, check_calibration, check_scene, draw_id

pytestmark = pytest.mark.slow

#: 1440 x 1080 mono JPEG, 2448 x 2048 (5 MP) Bayer PNG. The next to add: (4, SMALL), 752 x 480 mono PNG
#: behind a 6 mm lens (100 s).
SWEEP = ((6, MID), (0, LARGE))


@pytest.mark.parametrize("draw", SWEEP, ids=draw_id)
def test_sweep_draw_calibrates(draw):
    check_calibration(*draw)


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("scene", SCENES)
@pytest.mark.parametrize("draw", SWEEP, ids=draw_id)
def test_sweep_scene(draw, scene, mode):
    check_scene(*draw, scene, mode)
