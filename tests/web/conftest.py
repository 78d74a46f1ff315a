
import pytest

from psvs import default_rig
from psvs.live.simulated import disc_scene
from psvs.web.app import create_app
from psvs.web.sources import scene_source
from tests.support.web import DISC, serving


@pytest.fixture(scope="session")
def disc_source():
    rig = default_rig()
    return scene_source("disc", disc_scene(**DISC), rig), rig


@pytest.fixture
def live_server(disc_source):
    """The app on the simulated disc, served for real."""
    source, rig = disc_source
    with serving(create_app(source, rig)) as url:
        yield url


