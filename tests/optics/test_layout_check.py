"""The layout check every measuring command asks (psvs.optics.layout_check): a clear verdict kept per rig
content, in memory and in the cache folder; never for another rig's values; a blocked layout refused every
time; no cache folder, the same answers."""
import dataclasses

import pytest

from psvs import default_rig
from psvs.errors import RigGeometryError
from psvs.io.params import load_rig
from psvs.optics import design
from psvs.optics.layout_check import check_clear, forget, layout_key
from psvs.optics.rig import Calibration


@pytest.fixture
def folder(tmp_path, monkeypatch):
    monkeypatch.setenv("PSVS_CACHE_DIR", str(tmp_path / "cache"))
    forget()
    yield tmp_path / "cache"
    forget()


def _designs(monkeypatch) -> list:
    """Count the designs check_clear makes from now on (each still made, by the real design)."""
    calls = []
    real = design.design_mirrors

    def counted(rig, **kw):
        calls.append(rig)
        return real(rig, **kw)
    monkeypatch.setattr(design, "design_mirrors", counted)
    return calls


def test_a_clear_verdict_is_kept_per_rig_content(folder, monkeypatch):
    rig = load_rig("misaligned")
    calls = _designs(monkeypatch)
    assert check_clear(rig) is rig and len(calls) == 1
    markers = list((folder / "layout").iterdir())
    assert [p.name for p in markers] == [f"{layout_key(rig)}.clear"]
    assert check_clear(rig) is rig and len(calls) == 1            # this process remembers it
    forget()                                                       # a new process: the folder's file
    assert check_clear(load_rig("misaligned")) is not None and len(calls) == 1
    moved = rig.replace(m1_axis_distance_mm=rig.mirrors.m1_axis_distance_mm + 1e-9)
    assert check_clear(moved) is moved and len(calls) == 2         # another value: designed again
    assert len(list((folder / "layout").iterdir())) == 2


def test_the_key_is_the_rigs_values_not_its_record():
    rig = default_rig()
    recorded = dataclasses.replace(rig, calibration=Calibration(0.03, 0.03, 0.03, 20, "20 card"))
    assert layout_key(recorded) == layout_key(rig) and len(layout_key(rig)) == 64
    assert layout_key(rig.replace(baseline_mm=100.5)) != layout_key(rig)
    assert layout_key(rig.replace(pixel_pitch_mm=(0.0099, 0.0099))) != layout_key(rig)


def test_a_blocked_layout_is_refused_every_time_and_never_kept(folder, monkeypatch):
    rig = default_rig().replace(baseline_mm=5.0, plate_thickness_mm=30.0)
    calls = _designs(monkeypatch)
    for _ in range(2):
        with pytest.raises(RigGeometryError, match="^rig x is no layout a build can have: "):
            check_clear(rig, "rig x")
    assert len(calls) == 2 and not (folder / "layout").exists()


def test_no_cache_folder_gives_the_same_answers(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("a file where the cache folder would be")
    monkeypatch.setenv("PSVS_CACHE_DIR", str(blocker / "cache"))
    forget()
    calls = _designs(monkeypatch)
    rig = load_rig("mv1440")
    assert check_clear(rig) is rig and check_clear(rig) is rig and len(calls) == 1
    forget()
    with pytest.raises(RigGeometryError):
        check_clear(rig.replace(baseline_mm=5.0, plate_thickness_mm=30.0))
    forget()
