"""psvs mount on the command line: what it writes, what it refuses (exit 1 naming the culprit, exit 2 on bad
input or without the cad extra), and that a refusal leaves the folder as it was; psvs adjust --mount and
calibrate --adjust DIR take the seats it wrote."""
from __future__ import annotations

import re
import sys
import tomllib

import pytest

from psvs.cli.mount_cmd import FILES
from psvs.io.params import dumps_rig, load_rig
from psvs.mount.files import read_mount
from psvs.mount.guide import alignment_guide
from psvs.rigs import shipped_rig_path
from tests.support.cli import run


@pytest.fixture(scope="module")
def mount_dir(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mount")
    from psvs.cli.main import main
    assert main(["mount", "--rig", "clear", "-o", str(folder / "m")]) == 0
    return folder / "m"


def test_mount_writes_every_file(mount_dir):
    assert sorted(p.name for p in mount_dir.iterdir()) == sorted(FILES)
    data = tomllib.loads((mount_dir / "mount.toml").read_text())
    assert data["checks"]["rays"] >= 10_000 and data["checks"]["blocked"] == 0 and data["checks"]["watertight"]


def test_adjust_on_the_mounts_seats(capsys, mount_dir):
    """psvs adjust --mount DIR turns the screws of the seats in mount.toml: the same guide as the library's on
    those seats (its first line, the offsets and every turn's line)."""
    code, text, err = run(capsys, "adjust", "misaligned", "--rig", "clear", "--mount", str(mount_dir))
    assert code == 0, err
    from psvs.mount.report import format_guide
    g = alignment_guide(load_rig(shipped_rig_path("misaligned")), read_mount(mount_dir)[1])
    assert text.strip() == format_guide(g).strip()


def test_the_pitch_of_the_screws_fitted_turns_them(capsys, mount_dir):
    """The mount's mount.toml lists M3 x 0.5 (its BOM); screws of another pitch fitted (--pitch-mm 0.35, trial
    49: it was ignored, every turn 43 % too far): the guide on the same seats with that pitch, and a line
    saying which pitch it used. The same pitch given: no line."""
    from dataclasses import replace

    from psvs.mount.report import format_guide
    assert read_mount(mount_dir)[1]["m1"].pitch_mm == 0.5
    code, text, err = run(capsys, "adjust", "misaligned", "--rig", "clear", "--mount", str(mount_dir),
                          "--pitch-mm", "0.35")
    assert code == 0, err
    seats = {n: replace(s, pitch_mm=0.35) for n, s in read_mount(mount_dir)[1].items()}
    g = alignment_guide(load_rig(shipped_rig_path("misaligned")), seats)
    assert text.strip() == format_guide(g).strip() and "0.35 mm pitch" in text
    assert err.strip() == f"screws of 0.35 mm pitch (--pitch-mm), not the 0.5 mm that {mount_dir}/mount.toml lists"
    code, same, err = run(capsys, "adjust", "misaligned", "--rig", "clear", "--mount", str(mount_dir),
                          "--pitch-mm", "0.5")
    assert code == 0 and err == ""
    code, listed, _ = run(capsys, "adjust", "misaligned", "--rig", "clear", "--mount", str(mount_dir))
    assert same == listed != text


def test_a_mount_of_another_design_is_refused(capsys, mount_dir):
    """Issue 41's second trial: `adjust misaligned --rig clear --mount` with a mount psvs made for mv1440 (M1 at
    16 mm for clear's 22) answered turns, some the wrong way round. The seats' contacts are checked on the
    design's glasses first (this mount is clear's: on default's glasses too, the same planes)."""
    from psvs.mount.files import check_seats_on
    data = tomllib.loads((mount_dir / "mount.toml").read_text())
    check_seats_on(data, load_rig(shipped_rig_path("default")), "m")          # the same glass planes
    code, _, err = run(capsys, "adjust", "misaligned", "--rig", "mv1440_misaligned", "--mount", str(mount_dir))
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    moved = load_rig(shipped_rig_path("clear")).replace(m1_axis_distance_mm=16.0, m2_axis_distance_mm=38.0)
    with pytest.raises(ValueError, match=r"^m: its seats are not on this design's glasses \(M1's pivot contact "
                                         r"stands [+-]\d+\.\d\d mm off its glass's back face\): a mount made for "
                                         r"another design$"):
        check_seats_on(data, moved, "m")


@pytest.mark.parametrize("argv, says", [
    (("mount", "--rig", "clear", "-o", "{d}", "--wall-mm", "-1"), "wall_mm"),
    (("mount", "--rig", "clear", "-o", "{d}", "--interface", "m42"), "invalid choice"),
    (("mount", "--rig", "clear", "-o", "{d}", "--clearance-mm", "5"), "clearance_mm"),
    (("adjust", "misaligned", "--rig", "clear", "--mount", "{d}"), "no mount.toml"),
    (("calibrate", "{d}", "--rig", "clear", "-o", "{d}/cal.toml", "--adjust", "{d}"), "no mount.toml"),
])
def test_bad_input_is_one_line_and_exit_2(capsys, tmp_path, argv, says):
    code, text, err = run(capsys, *[a.format(d=tmp_path) for a in argv])
    assert code == 2 and len(err.strip().splitlines()) == 1 and says in err, err
    assert not (tmp_path / "mount.toml").exists()


@pytest.mark.parametrize("rig_text, says", [
    ({"m1_axis_distance_mm": 25.0, "m2_axis_distance_mm": 45.0}, "M2 cuts through the M1 plate"),
    (None, "M1's contact"),
])
def test_a_mount_that_cannot_be_built_exits_1_and_writes_nothing(capsys, tmp_path, rig_text, says):
    """A blocked design, or M1's contacts in the light: exit 1 naming the culprit; an older mount.toml in the
    folder stays as it was and nothing else is written."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "mount.toml").write_text("old")
    rig = "clear"
    if rig_text is not None:
        rig = str(tmp_path / "blocked.toml")
        (tmp_path / "blocked.toml").write_text(dumps_rig(load_rig(shipped_rig_path("default")).replace(**rig_text)))
    extra = () if rig_text is not None else ("--m1-border-mm", "8")
    code, text, err = run(capsys, "mount", "--rig", rig, "-o", str(out), *extra)
    assert code == 1 and len(err.strip().splitlines()) == 1 and says in err, err
    assert sorted(p.name for p in out.iterdir()) == ["mount.toml"] and (out / "mount.toml").read_text() == "old"


def test_docs_refusal_example_is_what_psvs_prints(capsys, tmp_path):
    """docs/mount.md's refused layout, as printed; the border it suggests then builds."""
    from pathlib import Path
    doc = (Path(__file__).resolve().parents[2] / "docs" / "mount.md").read_text().splitlines()
    k = doc.index("psvs mount --rig default -o out --m1-border-mm 8     # exit status 1, nothing written:")
    code, _, err = run(capsys, "mount", "--rig", "default", "-o", str(tmp_path / "out"), "--m1-border-mm", "8")
    assert code == 1 and err.strip() == doc[k + 1]
    border = re.search(r"--m1-border-mm (\d+) \(now", err).group(1)
    code, _, err = run(capsys, "mount", "--rig", "default", "-o", str(tmp_path / "out"), "--m1-border-mm", border)
    assert code == 0, err


def test_without_the_cad_extra_exit_2_naming_it(capsys, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "build123d", None)     # as when the import finds no build123d
    code, text, err = run(capsys, "mount", "--rig", "clear", "-o", str(tmp_path / "m"))
    assert code == 2, err
    assert err == "psvs mount: the mount needs the optional extra 'cad' (build123d): pip install 'psvs[cad]'\n"
    assert not (tmp_path / "m").exists()
