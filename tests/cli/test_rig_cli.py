"""Shipped rigs (a pip user gets rig files): ``--rig NAME``, ``psvs rig list|show``."""
import tomllib
from pathlib import Path

import pytest

from psvs import default_rig
from psvs.io.params import load_rig, rig_from_dict, save_rig
from psvs.rigs import SHIPPED, shipped_rig_path
from tests.support.cli import run

ROOT = Path(__file__).resolve().parents[2]


def test_shipped_rigs_load_by_name_and_agree_with_the_repository_examples():
    for name in SHIPPED:
        assert load_rig(name) == load_rig(ROOT / "examples" / "rigs" / f"{name}.toml")
    assert load_rig("default") == default_rig()   # the file and the code's default are one rig
    assert not load_rig("misaligned").as_designed and load_rig("clear").as_designed


def test_unknown_name_lists_the_shipped_rigs():
    shipped = "default, clear, misaligned, misaligned_knocked, mv1440, mv1440_misaligned"
    message = rf"rig file not found: nope \(shipped rigs: {shipped}\)"
    with pytest.raises(FileNotFoundError, match=message):
        load_rig("nope")


def test_rig_show_prints_toml_that_reads_back(capsys, tmp_path):
    code, out, _ = run(capsys, "rig", "show", "misaligned")
    assert code == 0 and out == shipped_rig_path("misaligned").read_text()
    assert rig_from_dict(tomllib.loads(out)) == load_rig("misaligned")
    mine = tmp_path / "mine.toml"
    save_rig(default_rig().replace(baseline_mm=120.0), mine)
    code, out, _ = run(capsys, "rig", "show", str(mine))
    assert code == 0 and rig_from_dict(tomllib.loads(out)).mirrors.baseline_mm == 120.0


def test_rig_list_and_errors(capsys):
    code, out, _ = run(capsys, "rig", "list")
    assert code == 0 and [ln.split()[0] for ln in out.splitlines()] == list(SHIPPED)
    assert "M1 at 22 mm, M2 at 44 mm, as designed" in out.splitlines()[0]
    code, _, err = run(capsys, "rig", "show")
    assert code == 2 and "needs a shipped rig's name or a rig file" in err
    code, _, err = run(capsys, "rig", "show", "nope")
    shipped = "default, clear, misaligned, misaligned_knocked, mv1440, mv1440_misaligned"
    assert code == 2 and f"shipped rigs: {shipped}" in err
