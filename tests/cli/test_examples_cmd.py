"""``psvs examples``: the shipped example files written out, read back by value (the README's commands read them
from a pip install)."""
import csv
import tomllib
from pathlib import Path

import numpy as np

from tests.support.cli import run

REPO_EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _table(path: Path) -> np.ndarray:
    with path.open(newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    return np.array(rows[1:], dtype=float)


def test_written_examples_are_the_repository_s_and_measure_their_truth(tmp_path, capsys):
    out = tmp_path / "ex"
    code, text, err = run(capsys, "examples", "-o", str(out))
    assert (code, err) == (0, "")
    written = sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file())
    assert "8 example file(s) written" in text and len(written) == 8
    for name in written:                                    # the files the repository's examples/ links to
        assert (out / name).read_bytes() == (REPO_EXAMPLES / name).read_bytes(), name
    # by value: the scene and tolerance files parse (tomllib, not psvs), the matches triangulate to their truth
    assert tomllib.loads((out / "scenes/desk.toml").read_text(encoding="utf-8"))["name"] == "desk"
    assert "tolerances" in tomllib.loads((out / "tolerances_small.toml").read_text(encoding="utf-8"))
    code, _, err = run(capsys, "triangulate", "--rig", "clear", str(out / "matches.csv"), "--model", "exact",
                       "-o", str(tmp_path / "points.csv"))
    assert code == 0, err
    points, truth = _table(tmp_path / "points.csv"), _table(out / "matches_truth.csv")
    assert points.shape == (6, 5) and np.all(points[:, 4] == 1)             # X, Y, Z, Z_sigma_mm, valid
    assert np.all((points[:, 3] > 0) & (points[:, 3] < 2.0))                # 0.1 px of match noise: a few 0.1 mm
    np.testing.assert_allclose(points[:, :3], truth, atol=1e-6)
    code, _, err = run(capsys, "simulate", str(out / "scenes/desk.toml"), "-o", str(tmp_path / "desk.png"),
                       "--rig", "default", "--seed", "1")
    assert code == 0, err                                   # the scene's assets resolve beside it


def test_a_second_run_writes_nothing_and_an_edited_file_is_kept(tmp_path, capsys):
    out = tmp_path / "ex"
    assert run(capsys, "examples", "-o", str(out))[0] == 0
    stamp = {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()}
    code, text, _ = run(capsys, "examples", "-o", str(out))
    assert code == 0 and "0 example file(s) written" in text and "(8 already there)" in text
    assert stamp == {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()}
    mine = b"u_l,v_l,u_r,v_r\n1,2,3,4\n"
    (out / "matches.csv").write_bytes(mine)
    (out / "scenes/desk.toml").unlink()
    code, _, err = run(capsys, "examples", "-o", str(out))
    assert code == 2 and "matches.csv exists with other contents" in err and len(err.strip().splitlines()) == 1
    assert (out / "matches.csv").read_bytes() == mine and not (out / "scenes/desk.toml").exists()


def test_a_folder_where_a_file_goes_is_named_as_a_folder(tmp_path, capsys):
    """Trial 32: a folder named matches.csv in the way was 'exists with other contents'; nothing is written."""
    out = tmp_path / "ex"
    (out / "matches.csv").mkdir(parents=True)
    code, _, err = run(capsys, "examples", "-o", str(out))
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "matches.csv is a folder where the example file goes: not replaced (nothing written)" in err
    assert [p.name for p in out.iterdir()] == ["matches.csv"] and not any((out / "matches.csv").iterdir())
