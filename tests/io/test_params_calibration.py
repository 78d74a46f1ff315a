"""The rig file's [calibration] table (written by psvs calibrate): read back by value with tomllib and json,
round trip, errors."""
import dataclasses
import json
import tomllib

import pytest

from psvs.io.params import dumps_rig, load_rig, rig_from_dict, save_rig
from psvs.optics.rig import Calibration


def test_calibration_round_trips_by_value(tmp_path):
    calibration = Calibration(0.0312, 0.0301, 0.0323, 17, "16 card, 1 sweep")
    rig = dataclasses.replace(load_rig("misaligned"), calibration=calibration)
    for suffix in (".toml", ".json"):
        path = tmp_path / f"rig{suffix}"
        save_rig(rig, path)
        raw = tomllib.loads(path.read_text()) if suffix == ".toml" else json.loads(path.read_text())
        assert raw["calibration"] == {"rms_px": 0.0312, "rms_left_px": 0.0301, "rms_right_px": 0.0323,
                                      "images": 17, "kinds": "16 card, 1 sweep"}
        back = load_rig(path)
        assert back == rig and back.calibration == rig.calibration
    assert "[calibration]" not in dumps_rig(load_rig("misaligned"))       # a design carries none
    assert load_rig("misaligned").replace(focal_length_mm=11.0).calibration is None
    assert rig.replace(focal_length_mm=11.0).calibration == rig.calibration


@pytest.mark.parametrize("table, message", [
    ({"rms_px": 0.1, "rms_left_px": 0.1, "rms_right_px": 0.1}, "missing key calibration.images"),
    ({"rms_px": -0.1, "rms_left_px": 0.1, "rms_right_px": 0.1, "images": 3}, "calibration.rms_px"),
    ({"rms_px": 0.1, "rms_left_px": 0.1, "rms_right_px": 0.1, "images": 2.5}, "calibration.images"),
    ({"rms_px": 0.1, "rms_left_px": 0.1, "rms_right_px": 0.1, "images": 3, "when": 1}, "when"),
])
def test_bad_calibration_tables(table, message):
    from psvs.io.params import rig_to_dict
    data = rig_to_dict(load_rig("default")) | {"calibration": table}
    with pytest.raises(ValueError, match=message):
        rig_from_dict(data)
