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
    with pytest.raises(TypeError, match=r"^a\.b\[1\]: cannot write float32"):
        dumps_toml({"a": {"b": [1.0, np.float32(2.0)]}})
    with pytest.raises(TypeError, match=r"^a: cannot write NoneType None"):
        dumps_toml({"a": None})


def test_arrays_short_inline_long_one_item_a_line():
    """A rig's arrays each on one line (as the shipped rigs), a 4 x 4 matrix one row a line, a long list one
    number a line; tomllib reads every number back exactly, NumPy's float64 and int64 as plain numbers."""
    from psvs.io.params import rig_to_dict
    for name, count in (("misaligned", 9), ("clear", 11)):
        rig = load_rig(name)
        text = dumps_rig(rig)
        arrays = [line for line in text.splitlines() if " = [" in line]
        assert len(arrays) == count and all(line.endswith("]") for line in arrays), name
        assert tomllib.loads(text) == rig_to_dict(rig)
        assert load_rig(name) == rig
    assert "distortion = [-0.2, 0.45, 0.0012, -0.0009, -0.03]" in dumps_rig(load_rig("misaligned")).splitlines()
    assert "along_mm = [-6.866250675245926, 14.39631001284942]" in dumps_rig(load_rig("clear")).splitlines()
    matrix = [[0.1234567890123456, -0.9876543210987654, 1 / 3, -31.2]] * 3 + [[0.0, 0.0, 0.0, 1.0]]
    data = {"t": {"m": matrix, "long": [k / 7 for k in range(30)], "five": [1 / 3, 2 / 3, 1e-17, -1e300, 7.0],
                  "np": [np.float64(0.1), np.int64(3)], "empty": [], "names": ["a", "b"]}}
    text = dumps_toml(data)
    lines = text.splitlines()
    k = lines.index("m = [")
    assert lines[k + 1:k + 6] == ["    [0.1234567890123456, -0.9876543210987654, 0.3333333333333333, -31.2],"] * 3 + \
        ["    [0.0, 0.0, 0.0, 1.0],", "]"]
    assert lines[lines.index("long = [") + 8] == "    1.0,"
    assert "five = [0.3333333333333333, 0.6666666666666666, 1e-17, -1e+300, 7.0]" in lines
    assert 'np = [0.1, 3]' in lines and "empty = []" in lines and 'names = ["a", "b"]' in lines
    back = tomllib.loads(text)["t"]
    assert back == {**data["t"], "np": [0.1, 3]} and type(back["np"][1]) is int
