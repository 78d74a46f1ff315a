"""The [camera.acquisition] table: read from a rig file (which still loads as a rig), checked, written back
by a recording and read again; the Acquisition record's checks and merge; the --camera spec."""
import pytest

from psvs.io.acquisition import acquisition_from_table, dumps_acquisition, load_acquisition
from psvs.io.params import load_rig
from psvs.live.camera import Acquisition, CameraSpec, parse_camera
from psvs.rigs import shipped_rig_path

TABLE = """
[camera.acquisition]
exposure_us = 2000
pixel_format = "Mono12"
trigger = "line1"
auto_gain = true
settings_file = "ace.pfs"
[camera.acquisition.features]
BlackLevel = 0
ReverseX = true
"""


def test_a_rig_file_with_an_acquisition_table(tmp_path):
    rig = tmp_path / "rig.toml"
    rig.write_text(shipped_rig_path("mv1440").read_text() + TABLE)
    assert load_rig(rig).camera.image_size_px == (1440, 1080)           # the rig itself is unchanged
    got = load_acquisition(rig)
    assert got == {"exposure_us": 2000.0, "pixel_format": "Mono12", "trigger": "line1", "auto_gain": True,
                   "settings_file": str(tmp_path / "ace.pfs"), "features": (("BlackLevel", "0"), ("ReverseX", "true"))}
    acq = Acquisition(**got)
    over = acq.merged(Acquisition(exposure_us=500.0, features=(("Gamma", "1"),)))
    assert over.exposure_us == 500.0 and over.pixel_format == "Mono12" and over.auto_gain
    assert over.features == (("BlackLevel", "0"), ("ReverseX", "true"), ("Gamma", "1"))
    assert load_acquisition(shipped_rig_path("mv1440")) == {}


def test_a_recorded_table_reads_back(tmp_path):
    settings = {"camera": "Basler acA1440-220um", "serial": "40123456", "pixel_format": "Mono12", "bits": 12,
                "exposure_us": 2000.0, "gain_db": 0.0, "frame_rate_hz": 30.0, "auto_exposure": False,
                "auto_gain": False, "trigger": "software", "features": {"BlackLevel": "0"}}
    import tomllib
    table = tomllib.loads(dumps_acquisition(settings))["camera"]["acquisition"]
    got = acquisition_from_table(table, "camera.acquisition")
    assert got["pixel_format"] == "Mono12" and got["exposure_us"] == 2000.0 and got["trigger"] == "software"
    assert got["features"] == (("BlackLevel", "0"),)
    Acquisition(**{k: v for k, v in got.items()})


@pytest.mark.parametrize("table, error, message", [
    ({"exposure": 1}, ValueError, "unknown key camera.acquisition.exposure"),
    ({"exposure_us": "fast"}, ValueError, "camera.acquisition.exposure_us must be a finite number"),
    ({"auto_gain": 1}, ValueError, "camera.acquisition.auto_gain must be true or false"),
    ({"pixel_format": 12}, ValueError, "camera.acquisition.pixel_format must be a string"),
    ({"features": [1]}, ValueError, r"\[camera.acquisition.features\] must be a table"),
])
def test_table_errors(table, error, message):
    with pytest.raises(error, match=message):
        acquisition_from_table(table, "camera.acquisition")


def test_acquisition_checks():
    with pytest.raises(ValueError, match="exposure_us must be > 0"):
        Acquisition(exposure_us=0.0)
    with pytest.raises(ValueError, match="trigger must be one of software, line1"):
        Acquisition(trigger="line2")
    with pytest.raises(ValueError, match="frame_rate_hz must be a number"):
        Acquisition(frame_rate_hz=float("nan"))
    assert not Acquisition().asks_anything() and Acquisition(auto_gain=True).asks_anything()


def test_camera_specs():
    assert parse_camera("0") == CameraSpec("opencv", "0") and str(parse_camera(" 2 ")) == "2"
    assert parse_camera("basler:40123456") == CameraSpec("basler", "40123456")
    assert parse_camera("Basler") == CameraSpec("basler", "0") and str(parse_camera("basler:1")) == "basler:1"
    with pytest.raises(ValueError, match="--camera must be an OpenCV index"):
        parse_camera("-1")
    with pytest.raises(ValueError, match="--camera must be an OpenCV index"):
        parse_camera("²")                            # a digit to str.isdigit, no number to int()
    assert parse_camera("2147483647") == CameraSpec("opencv", "2147483647")
    with pytest.raises(ValueError, match=r"--camera 99999999999: an OpenCV index is at most 2147483647"):
        parse_camera("99999999999")       # a trial's: OpenCV's "Bad argument", exit 1 (live, capture, serve)
