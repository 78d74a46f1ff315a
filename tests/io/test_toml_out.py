"""Rig files hold plain numbers whatever the rig was built from (a calibration gives NumPy scalars): the
written TOML and JSON read back with the standard readers, by value."""
import json
import tomllib

import numpy as np
import pytest

from psvs import default_rig
from psvs.io.params import dumps_rig, load_rig, save_rig
from psvs.io.tomlfile import dumps_toml


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_numpy_scalars_write_plain_numbers(tmp_path, suffix):
    rig = default_rig().replace(focal_length_mm=np.float64(11.300391427337438),
                                principal_point_px=(np.float64(320.25), np.float32(240.5)),
                                plate_thickness_mm=np.float64(2.91), baseline_mm=np.float64(100.06))
    path = tmp_path / f"rig{suffix}"
    save_rig(rig, path)
    text = path.read_text()
    assert "np." not in text
    data = json.loads(text) if suffix == ".json" else tomllib.loads(text)
    assert data["camera"]["focal_length_mm"] == 11.300391427337438
    assert data["camera"]["principal_point_px"] == [320.25, 240.5]
    assert data["mirrors"]["baseline_mm"] == 100.06
    assert load_rig(path) == rig.replace(focal_length_mm=11.300391427337438, principal_point_px=(320.25, 240.5),
                                         plate_thickness_mm=2.91, baseline_mm=100.06)


def test_writer_refuses_what_it_cannot_write():
    with pytest.raises(TypeError):
        dumps_toml({"x": None})
    assert tomllib.loads(dumps_rig(default_rig()))["mirrors"]["angle_deg"] == 45.0
