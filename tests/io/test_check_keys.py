"""One wording for a table's keys in every file psvs reads (psvs.io.schema.check_keys): a table that is not
one, an unknown key (named with its path, and what is allowed), a missing key; and no other module words it."""
import ast
import re
from pathlib import Path

import pytest

from psvs.io.schema import check_keys

SRC = Path(__file__).resolve().parents[2] / "src" / "psvs"


@pytest.mark.parametrize("table, kw, message", [
    ([1], {}, r"^\[camera\.acquisition\] must be a table, got list$"),
    ({"a": 1, "zz": 2, "b": 3}, {"required": ("a",), "optional": ("b",)},
     r"^unknown key camera\.acquisition\.zz \(allowed: a, b\)$"),
    ({"b": 3}, {"required": ("a", "c"), "optional": ("b",)}, r"^missing key camera\.acquisition\.a$"),
    ({"rows": 4, "marker_mm": 3}, {"required": ("rows",), "optional": ("kind",), "what": "circles"},
     r"^unknown key camera\.acquisition\.marker_mm for a circles \(allowed: rows, kind\)$"),
    ({}, {"required": ("rows", "cols"), "what": "circles"},
     r"^missing key camera\.acquisition\.rows \(a circles needs rows, cols\)$"),
])
def test_each_fault_is_one_line_naming_the_key(table, kw, message):
    with pytest.raises(ValueError, match=message):
        check_keys(table, "camera.acquisition", **kw)


def test_a_good_table_is_returned_and_the_top_level_has_no_prefix():
    t = {"a": 1}
    assert check_keys(t, "x", ("a",), ("b",)) is t
    with pytest.raises(ValueError, match=r"^unknown key 3 \(allowed: name\)$"):
        check_keys({3: 1}, "", optional=("name",))


def test_no_other_module_words_a_key_fault():
    """The seven readers that each wrote their own 'unknown key' message call check_keys instead (a key that
    another key needs, e.g. a mirror's height_mm beside its along_mm, is the reader's own rule)."""
    worded = []
    for path in SRC.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) \
                    and re.match(r"\s*unknown key", node.value):
                worded.append(f"{path.relative_to(SRC)}:{node.lineno}")
    assert all(w.startswith("io/schema.py") for w in worded), worded
