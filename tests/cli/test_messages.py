"""Bad input answered in the user's words and units, in one line, before any work."""
import os

import numpy as np
import pytest

from psvs.io.images import write_png
from tests.support.cli import EXAMPLE, run


@pytest.fixture(scope="module")
def image(tmp_path_factory):
    path = tmp_path_factory.mktemp("img") / "c.png"
    write_png(path, np.full((480, 640), 40, np.uint8))
    return str(path)


def one_line(code, err, expected):
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1, err
    assert expected in err, err
    assert "Traceback" not in err and ".tmp" not in err


@pytest.mark.parametrize("argv, expected", [
    (["design", "--rig", EXAMPLE, "--margin-mm", "inf"], "--margin-mm must be a finite border >= 0 mm, got inf"),
    (["design", "--rig", EXAMPLE, "--margin-mm", "-1"], "--margin-mm must be a finite border >= 0 mm, got -1.0"),
    (["design", "--rig", EXAMPLE, "--far-mm", "300"], "--near-mm (400.0 mm) must be less than --far-mm (300.0 mm)"),
    (["simulate", "fig9:distance_mm=-100", "-o", "{tmp}/a.png"], "fig9: distance_mm must be > 0 mm, got '-100'"),
    (["simulate", "fig5a:distance_mm=nan", "-o", "{tmp}/a.png"], "fig5a: distance_mm must be finite, got 'nan'"),
    (["match", "{image}", "--rig", EXAMPLE, "--auto", "--far-mm", "inf", "-o", "{tmp}/m.json"],
     "--far-mm must be a finite depth in (0, 1e+07] mm, got inf"),
    (["match", "{image}", "--rig", EXAMPLE, "--auto", "--n-seeds", "3", "-o", "{tmp}/m.json"],
     "--n-seeds applies to --seed"),
    (["match", "{image}", "--rig", EXAMPLE, "--seed", "1,2", "--n-seeds", "0", "-o", "{tmp}/m.json"],
     "--n-seeds must be 2-100, got 0"),
    (["disparity", "{image}", "--rig", EXAMPLE, "--near-mm", "-5", "-o", "{tmp}/d.npy"],
     "--near-mm must be a finite depth in (0, 1e+07] mm, got -5.0"),
    (["disparity", "{image}", "--rig", EXAMPLE, "--near-mm", "30", "-o", "{tmp}/d.npy"],
     "--near-mm 30 mm lies inside the rig: its mirrors reach Z = 44.0 mm"),
    (["match", "{image}", "--rig", "mv1440", "--auto", "--near-mm", "60", "-o", "{tmp}/m.json"],
     "--near-mm 60 mm lies inside the rig: its mirrors reach Z = 75.9 mm"),
    (["check", "{image}", "--rig", EXAMPLE, "--near-mm", "44"], "--near-mm 44 mm lies inside the rig"),
    (["triangulate", "--rig", EXAMPLE, "{image}"], "c.png: not a CSV file (it is not UTF-8 text; an image?)"),
    (["match", "{image}", "--rig", EXAMPLE, "--auto", "-o", "{tmp}/m.json", "--csv", "{tmp}/dir.csv"],
     "dir.csv is a folder, not a file"),
    (["card-views", "{tmp}/cards", "--rig", EXAMPLE, "--seed", "-1"], "--seed must be >= 0, got -1"),
    (["sweep-views", "{tmp}/sw", "--rig", "default", "--step-mm", "0"], "--step-mm must be a finite number > 0 mm"),
    (["sweep-views", "{tmp}/sw", "--rig", "default", "--to-mm", "400"], "--to-mm (400.0 mm) must not be less than"),
    (["sweep-views", "{tmp}/sw", "--rig", "default", "--step-mm", "500"], "the sweep has 2 positions; give 3-60"),
])
def test_bad_input_in_the_users_terms(capsys, tmp_path, image, argv, expected):
    (tmp_path / "dir.csv").mkdir()
    earlier = tmp_path / "m.json"
    earlier.write_text("earlier")
    code, _, err = run(capsys, *[a.format(tmp=tmp_path, image=image) for a in argv])
    one_line(code, err, expected)
    assert earlier.read_text() == "earlier"   # checked before any output was written


def test_unwritable_output_names_the_file_not_the_temporary(capsys, tmp_path, monkeypatch):
    """As root every folder is writable, so the permission check is driven through os.access."""
    target = tmp_path / "mirrors.json"
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if str(p) == str(tmp_path) else real(p, mode))
    code, _, err = run(capsys, "design", "--rig", EXAMPLE, "-o", str(target))
    one_line(code, err, f"cannot write {target}: permission denied")
    assert not target.exists()


def test_atomic_write_error_names_the_target(tmp_path, monkeypatch):
    import tempfile

    from psvs.io.atomic import write_atomic

    def refuse(**kw):
        raise PermissionError(13, "Permission denied", str(tmp_path / ".x.json.abc.tmp"))
    monkeypatch.setattr(tempfile, "mkstemp", refuse)
    with pytest.raises(PermissionError) as info:
        write_atomic(tmp_path / "x.json", "{}")
    assert str(info.value) == f"cannot write {tmp_path / 'x.json'}: Permission denied"


@pytest.mark.parametrize("argv", [["track", "weld_seam", "--rig", "default", "-o"], ["table1", "-o"],
                                  ["card-views", "--rig", "default"], ["sweep-views", "--rig", "default"]])
def test_unwritable_output_folder_is_refused_before_the_work(capsys, tmp_path, monkeypatch, argv):
    """track used to fail after 33 s of tracking; every folder output is checked first (os.access driven,
    as root can write anywhere)."""
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if str(p) == str(tmp_path) else real(p, mode))
    run_dir = tmp_path / "run"
    code, _, err = run(capsys, *argv, str(run_dir))
    one_line(code, err, "cannot write output")
    assert f"{run_dir}: permission denied" in err and not run_dir.exists()
