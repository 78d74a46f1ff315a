"""psvs.io.schema: one reader of a table's keys, types and bounds (target files, acquisition tables, tolerance
studies read through it)."""
import ast
import math
import re
from pathlib import Path

import pytest

from psvs.io.schema import REQUIRED, Field, read_fields

SRC = Path(__file__).resolve().parents[2] / "src" / "psvs"


@pytest.mark.parametrize(("field", "given", "expected"), [
    (Field("number"), 3, 3.0), (Field("number", 0.0, low_open=True), 1e-9, 1e-9), (Field("integer", 2, 50), 50, 50),
    (Field("string", choices=("a", "b")), "b", "b"), (Field("flag"), False, False), (Field("table"), {}, {}),
    (Field("any"), [1, "x"], [1, "x"]),
])
def test_a_good_value_is_returned_as_its_type(field, given, expected):
    got = field.value(given, "t.k")
    assert got == expected and type(got) is type(expected)


@pytest.mark.parametrize(("field", "given", "message"), [
    (Field("number"), "3", "t.k must be a finite number, got str '3'"),
    (Field("number"), True, "t.k must be a finite number, got bool True"),
    (Field("number", note="mm"), math.nan, "t.k must be a finite number (mm), got float nan"),
    (Field("number", 0.0, low_open=True), 0.0, "t.k must be > 0, got 0.0"),
    (Field("number", 0.0), -1, "t.k must be >= 0, got -1"),
    (Field("number", high=5.0), 6.5, "t.k must be <= 5, got 6.5"),
    (Field("number", 0.0, 3.0, low_open=True), 0, "t.k must be > 0 and <= 3, got 0"),
    (Field("integer", 2, 50), 1, "t.k must be a whole number 2-50, got 1"),
    (Field("integer", 2, 50), 4.0, "t.k must be a whole number, got float 4.0"),
    (Field("string", choices=("card", "sweep")), "robot", "t.k must be one of card, sweep, got 'robot'"),
    (Field("string"), 12, "t.k must be a string, got int 12"),
    (Field("flag"), 1, "t.k must be true or false, got 1"),
    (Field("table"), [1], "[t.k] must be a table, got list"),
])
def test_a_bad_value_is_one_line_naming_key_type_and_bound(field, given, message):
    with pytest.raises(ValueError, match=f"^{re.escape(message)}$"):
        field.value(given, "t.k")


def test_read_fields_fills_defaults_and_leaves_out_what_has_none():
    schema = {"n": Field("integer", 1, 9, default=REQUIRED), "x": Field("number", default=2.5), "s": Field("string")}
    assert read_fields({"n": 3}, "a", schema) == {"n": 3, "x": 2.5}
    assert read_fields({"n": 3, "x": 1, "s": "q"}, "a", schema) == {"n": 3, "x": 1.0, "s": "q"}
    with pytest.raises(ValueError, match=r"^missing key a\.n$"):
        read_fields({"x": 1}, "a", schema)
    with pytest.raises(ValueError, match=r"^unknown key a\.y \(allowed: n, x, s\)$"):
        read_fields({"n": 1, "y": 1}, "a", schema)
    with pytest.raises(ValueError, match=r"^a\.n must be a whole number 1-9, got 10$"):
        read_fields({"n": 10}, "a", schema)
    with pytest.raises(ValueError, match="kind must be one of"):
        Field("float")


def test_only_the_schema_words_a_value_fault_of_a_file():
    """'must be a finite number' and 'must be true or false' are the schema's words; a reader that wrote its
    own would word it differently from the next one (the command line's options are not file values)."""
    worded = []
    for path in SRC.rglob("*.py"):
        if path.parent.name == "cli":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and re.search(
                    r"must be (true or false|a finite number)", node.value):
                worded.append(f"{path.relative_to(SRC)}:{node.lineno}")
    assert worded and all(w.startswith("io/schema.py") for w in worded), worded
