import math
import tomllib

import pytest

from psvs.io.toml_out import dumps_toml


def test_round_trip_through_tomllib():
    data = {
        "flag": True, "count": 3, "name": 'say "hi"\n\u00e9', "x": 0.1 + 0.2, "bad": float("nan"),
        "far": float("-inf"), "pair": [1.5, -2.25], "words": ["a", "b"],
        "table": {"k": 1, "sub": {"deep": [1, 2, 3]}},
        "rows": [{"name": "M1", "w": 2.5}, {"name": "M2", "w": 3.5}],
    }
    back = tomllib.loads(dumps_toml(data))
    assert math.isnan(back.pop("bad"))
    data.pop("bad")
    assert back == data


def test_unsupported_value():
    with pytest.raises(TypeError, match="cannot write NoneType None to TOML"):
        dumps_toml({"x": None})
