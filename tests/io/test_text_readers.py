"""psvs's text readers: UTF-8 with a byte-order mark (what spreadsheet programs write) reads as without it;
a file nested too deep, not UTF-8, or with a CSV cell over the csv module's limit is a one-line ValueError
naming the file."""
import numpy as np
import pytest

from psvs.calibrate.sweep import read_sweep
from psvs.io.params import load_rig
from psvs.io.points import read_matches_csv
from psvs.io.text import read_csv_rows
from psvs.io.tomlfile import load_toml, update_toml
from psvs.robot.handeye_io import read_views, write_views
from psvs.robot.handeye_session import CELL_GRID
from tests.support.cli import EXAMPLE

BOM = "\ufeff"


def test_a_rig_file_with_a_byte_order_mark_reads_as_without(tmp_path):
    text = open(EXAMPLE, encoding="utf-8").read()
    for suffix in (".toml", ".json"):
        plain, marked = tmp_path / f"plain{suffix}", tmp_path / f"marked{suffix}"
        if suffix == ".json":
            import json
            import tomllib
            text = json.dumps(tomllib.loads(text))
        plain.write_text(text, encoding="utf-8")
        marked.write_text(BOM + text, encoding="utf-8")
        assert marked.read_bytes().startswith(b"\xef\xbb\xbf")
        assert load_toml(marked, "rig") == load_toml(plain, "rig")
        assert load_rig(marked) == load_rig(plain)


def test_a_matches_csv_with_a_byte_order_mark_keeps_its_first_column(tmp_path):
    path = tmp_path / "m.csv"
    path.write_bytes(b"\xef\xbb\xbfu_l,v_l,u_r,v_r\r\n1,2,3,4\r\n5,6,7,8\r\n")   # as Excel writes "CSV UTF-8"
    left, right = read_matches_csv(path)
    assert left.tolist() == [[1, 2], [5, 6]] and right.tolist() == [[3, 4], [7, 8]]


def test_a_sweep_csv_with_a_byte_order_mark(tmp_path):
    (tmp_path / "sweep.csv").write_text(BOM + "image,position_mm\na.png,700.5\nb.png,710\n", encoding="utf-8")
    assert read_sweep(tmp_path) == [(tmp_path / "a.png", 700.5), (tmp_path / "b.png", 710.0)]


def test_flange_poses_with_a_byte_order_mark(tmp_path):
    images = [np.full((12, 16), 40 * k, np.uint8) for k in range(3)]
    flanges = [np.eye(4) for _ in range(3)]
    for k, F in enumerate(flanges):
        F[:3, 3] = [k, 2 * k, 300.0]
    write_views(tmp_path, images, flanges, CELL_GRID)
    poses = tmp_path / "flange_poses.csv"
    poses.write_text(BOM + poses.read_text(encoding="utf-8"), encoding="utf-8")
    got_images, got_flanges, grid = read_views(tmp_path)
    assert grid == CELL_GRID and all(np.array_equal(a, b) for a, b in zip(got_images, images, strict=True))
    assert all(np.allclose(a, b) for a, b in zip(got_flanges, flanges, strict=True))


@pytest.mark.parametrize("name, text", [
    ("deep.toml", "a = " + "[" * 5000 + "]" * 5000 + "\n"),
    ("deep_tables.toml", "a = " + "{b = " * 3000 + "1" + "}" * 3000 + "\n"),
    ("deep.json", "[" * 100000 + "]" * 100000),
    ("deep_objects.json", '{"a": ' * 5000 + "1" + "}" * 5000),
])
def test_a_file_nested_thousands_deep_is_one_value_error(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    kind = "JSON" if name.endswith(".json") else "TOML"
    with pytest.raises(ValueError, match=rf"^{path}: malformed {kind}: nested too deep$"):
        load_toml(path, "rig")


def test_a_template_nested_too_deep_is_a_value_error():
    with pytest.raises(ValueError, match="^malformed TOML rig template: TOML value nested more than 100 levels"):
        update_toml("a = " + "[" * 5000 + "]" * 5000 + "\n", {"a": 1}, "TOML rig template")


def test_a_file_that_is_not_utf8_is_named(tmp_path):
    path = tmp_path / "rig.toml"
    path.write_bytes(b"focal = 1\n\xff\xfe\x00binary")
    with pytest.raises(ValueError, match=rf"^{path}: not a TOML file \(it is not UTF-8 text; an image\?\)$"):
        load_toml(path, "rig")
    csv_path = tmp_path / "flange_poses.csv"
    csv_path.write_bytes(b"image,x_mm\n\x89PNG\xff")
    with pytest.raises(ValueError, match=rf"^{csv_path}: not a CSV file"):
        read_csv_rows(csv_path)


def test_a_csv_cell_over_the_csv_modules_limit_names_the_file_and_line(tmp_path):
    path = tmp_path / "m.csv"
    path.write_text("u_l,v_l,u_r,v_r\n1,2,3,4\n1,2,3," + "4" * 200_000 + "\n")
    with pytest.raises(ValueError, match=rf"^{path}:3: not a CSV file: field larger than field limit"):
        read_matches_csv(path)
