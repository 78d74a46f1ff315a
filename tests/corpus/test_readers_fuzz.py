"""Property tests (Hypothesis) over every reader psvs has: rig, scene, target, pipeline and hand-eye files
(TOML), the CSV tables (matches, known points, sweep.csv, flange poses), images and recordings. Whatever the
bytes, a reader returns a value that reads back or raises ValueError/TypeError/OSError with a one-line
message: never another exception (a traceback at the command line). The inputs are both arbitrary bytes and
valid files with their values replaced, keys dropped or added, and their bytes cut or flipped. Then the same
through the command line: exit 0 with a result that reads back, or exit 1/2 and one line, the earlier output
unchanged."""
from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.corpus.files import DEFAULT_RIG, texture_png
from tests.corpus.runner import PLANTED

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
REFUSALS = (ValueError, TypeError, OSError)
FUZZ = settings(max_examples=60, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])

# TOML values of every kind, nested a little: what a user may type where a number or a table belongs
leaf = st.one_of(st.none(), st.booleans(), st.integers(-10**12, 10**12),
                 st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=12))
value = st.recursive(leaf.filter(lambda v: v is not None), lambda children: st.one_of(
    st.lists(children, max_size=6), st.dictionaries(st.text(min_size=1, max_size=8), children, max_size=4)),
    max_leaves=12)


def _toml(data: dict) -> str:
    """TOML text of a nested dict (tomlkit writes any value TOML has; NaN and inf included)."""
    import tomlkit
    return tomlkit.dumps(data)


def _mutate(data: dict, draw_path, new) -> dict:
    """``data`` with the value at a key path replaced by ``new`` (or the key dropped when ``new`` is None)."""
    out = {k: (_mutate(v, draw_path[1:], new) if draw_path and k == draw_path[0] and isinstance(v, dict)
               and len(draw_path) > 1 else v) for k, v in data.items()}
    if draw_path and len(draw_path) == 1 or (draw_path and draw_path[0] not in out):
        if new is None:
            out.pop(draw_path[0], None)
        else:
            out[draw_path[0]] = new
    return out


def _paths(data: dict, prefix=()) -> list[tuple]:
    out = []
    for k, v in data.items():
        out.append((*prefix, k))
        if isinstance(v, dict):
            out += _paths(v, (*prefix, k))
    return out


def _check_reader(read, path: Path):
    """Call ``read(path)``: a value, or a refusal in one line."""
    try:
        return read(path)
    except REFUSALS as exc:
        msg = str(exc).strip()
        assert msg and len(msg.splitlines()) == 1, repr(msg)
        return None


def _toml_fuzz(base: dict, tmp_path: Path, suffix: str, read, back=None):
    """A strategy-driven check of one TOML reader on edits of ``base``."""
    paths = _paths(base)

    @FUZZ
    @given(st.sampled_from(paths), st.one_of(st.none(), value), st.booleans())
    def check(where, new, add):
        data = _mutate(base, (*where[:-1], where[-1] + "_x") if add else where, new)
        path = tmp_path / f"f{suffix}"
        try:
            path.write_text(_toml(data), encoding="utf-8")
        except Exception:       # a value tomlkit itself cannot write: nothing to read
            return
        got = _check_reader(read, path)
        if got is not None and back is not None:
            back(got, tmp_path)
    check()


def test_rig_files(tmp_path):
    from psvs.io.params import load_rig, save_rig

    def back(rig, folder):
        save_rig(rig, folder / "again.toml")
        assert load_rig(folder / "again.toml") == rig
    _toml_fuzz(tomllib.loads(DEFAULT_RIG), tmp_path, ".toml", load_rig, back)


def test_scene_files(tmp_path):
    from psvs.io.scene_file import load_scene
    base = tomllib.loads((EXAMPLES / "scenes" / "pattern.toml").read_text())
    (tmp_path / "assets").mkdir()
    _toml_fuzz(base, tmp_path, ".toml", load_scene)


def test_target_files(tmp_path):
    from psvs.targets.target_file import dumps_target, load_target

    def back(grid, folder):
        (folder / "t2.toml").write_text(dumps_target(grid))
        assert load_target(folder / "t2.toml") == grid
    base = {"target": {"kind": "circle_grid", "rows": 4, "cols": 6, "spacing_mm": 14.0, "diameter_mm": 7.0}}
    _toml_fuzz(base, tmp_path, ".toml", load_target, back)


def test_pipeline_files(tmp_path):
    from psvs.io.pipeline_file import load_pipeline
    grey = np.random.default_rng(0).integers(0, 256, (24, 32), dtype=np.uint8)

    def back(pipeline, folder):
        try:
            edges = pipeline.run(grey)
        except REFUSALS as exc:
            assert len(str(exc).strip().splitlines()) == 1
            return
        assert edges.shape == grey.shape and edges.dtype == bool
    base = {"steps": [{"op": "median", "ksize": 3}, {"op": "threshold", "level": 92}, {"op": "roberts"}]}
    _toml_fuzz(base, tmp_path, ".toml", load_pipeline, back)


def test_handeye_files(tmp_path):
    from psvs.robot.handeye_io import load_handeye
    from tests.corpus.cases import HANDEYE_OK
    _toml_fuzz(tomllib.loads(HANDEYE_OK), tmp_path, ".toml", load_handeye)


@FUZZ
@given(st.binary(max_size=400))
def test_any_bytes_as_any_text_file(tmp_path_factory, data):
    """Arbitrary bytes (binary, not UTF-8, a byte-order mark, half a table) given to every text reader."""
    from psvs.io.params import load_rig
    from psvs.io.pipeline_file import load_pipeline
    from psvs.io.points import read_csv_columns
    from psvs.io.scene_file import load_scene
    from psvs.robot.handeye_io import load_handeye
    from psvs.targets.target_file import load_target
    folder = tmp_path_factory.mktemp("bytes")
    for name, read in (("r.toml", load_rig), ("s.toml", load_scene), ("t.toml", load_target),
                       ("p.toml", load_pipeline), ("h.toml", load_handeye), ("r.json", load_rig),
                       ("m.csv", lambda p: read_csv_columns(p, ("u_l", "v_l", "u_r", "v_r")))):
        (folder / name).write_bytes(data)
        _check_reader(read, folder / name)


csv_cell = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr), st.text(max_size=6),
                     st.just(""), st.integers().map(str))


@FUZZ
@given(st.lists(st.lists(csv_cell, min_size=0, max_size=9), max_size=8), st.booleans(), st.booleans())
def test_csv_tables(tmp_path_factory, rows, header, bom):
    """Match and known-point tables and sweep.csv: any cells under a right or a wrong header."""
    from psvs.calibrate.sweep import read_sweep
    from psvs.io.points import read_csv_columns, read_matches_csv
    folder = tmp_path_factory.mktemp("csv")
    head = "u_l,v_l,u_r,v_r,X_mm,Y_mm,Z_mm" if header else "a,b"
    text = ("\ufeff" if bom else "") + head + "\n" + "".join(",".join(r) + "\n" for r in rows)
    (folder / "m.csv").write_text(text, encoding="utf-8")
    got = _check_reader(read_matches_csv, folder / "m.csv")
    if got is not None:
        assert got[0].shape[1] == 2 and got[1].shape == got[0].shape
    _check_reader(lambda p: read_csv_columns(p, ("u_l", "v_l", "u_r", "v_r", "X_mm", "Y_mm", "Z_mm")),
                  folder / "m.csv")
    (folder / "sweep.csv").write_text(text.replace(head, "image,position_mm" if header else head), encoding="utf-8")
    _check_reader(read_sweep, folder)


@pytest.fixture(scope="module")
def good_png() -> bytes:
    return texture_png(64, 48)


@FUZZ
@given(st.data())
def test_images(tmp_path_factory, good_png, data):
    """A valid PNG cut short, with bytes flipped, or with its header's size rewritten; and random bytes."""
    from psvs.io.images import read_grey
    raw = bytearray(good_png)
    how = data.draw(st.sampled_from(["cut", "flip", "random"]))
    if how == "cut":
        raw = raw[: data.draw(st.integers(0, len(raw)))]
    elif how == "flip":
        for _ in range(data.draw(st.integers(1, 8))):
            raw[data.draw(st.integers(0, len(raw) - 1))] = data.draw(st.integers(0, 255))
    else:
        raw = bytearray(data.draw(st.binary(max_size=300)))
    path = tmp_path_factory.mktemp("img") / "i.png"
    path.write_bytes(bytes(raw))
    img = _check_reader(read_grey, path)
    if img is not None:
        assert img.ndim == 2 and img.dtype == np.uint8


@FUZZ
@given(st.binary(max_size=600))
def test_recordings(tmp_path_factory, junk):
    """MCAP files: random bytes after the magic."""
    from psvs.robot.recording import read_recording
    folder = tmp_path_factory.mktemp("rec")
    (folder / "a.mcap").write_bytes(b"\x89MCAP0\r\n" + junk)
    _check_reader(read_recording, folder / "a.mcap")


@settings(max_examples=25, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(st.sampled_from(_paths(tomllib.loads(DEFAULT_RIG))), value)
def test_the_command_line_on_edited_rigs(tmp_path_factory, where, new):
    """``psvs triangulate --rig EDITED.toml`` on the shipped matches: exit 0 and a points file that reads
    back, or exit 1/2 in one line with the earlier points file unchanged."""
    import contextlib
    import io

    from psvs.cli.main import main
    from psvs.io.points import read_csv_columns
    folder = tmp_path_factory.mktemp("cli")
    try:
        (folder / "rig.toml").write_text(_toml(_mutate(tomllib.loads(DEFAULT_RIG), where, new)), encoding="utf-8")
    except Exception:
        return
    (folder / "out.csv").write_bytes(PLANTED)
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(["triangulate", "--rig", str(folder / "rig.toml"), str(EXAMPLES / "matches.csv"), "-o",
                     str(folder / "out.csv")])
    if code == 0:
        pts = read_csv_columns(folder / "out.csv", ("X_mm", "Y_mm", "Z_mm", "valid"))
        assert pts.shape[1] == 4
    else:
        assert code in (1, 2) and len(err.getvalue().strip().splitlines()) == 1, err.getvalue()
        assert (folder / "out.csv").read_bytes() == PLANTED
