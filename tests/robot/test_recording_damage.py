"""A psvs track recording whose /psvs/setup or /psvs/cycle records are damaged (adversarial trial: replay said
"SVD did not converge", "too many values to unpack" or "operands could not be broadcast"): read_recording and
psvs replay name the record and the field, exit 2."""
import numpy as np
import pytest

from psvs.cli.main import main
from psvs.io.telemetry import Telemetry
from psvs.robot.controller import TrackConfig
from psvs.robot.recording import read_recording

EYE = np.eye(4).ravel().tolist()


def _write(path, setup_change=None, cycle_change=None) -> None:
    """A two-cycle recording of the records a track run writes, with the changes ``{key: value}`` made."""
    cfg = TrackConfig()
    setup = {"config": {k: getattr(cfg, k) for k in cfg.__dataclass_fields__}, "cam2flange": EYE,
             "taught_mm": [500.0, 0.0, 100.0], "travel": [1.0, 0.0, 0.0], "seed_px": None}
    setup.update(setup_change or {})
    with Telemetry(path, t0_ns=1_700_000_000 * 10**9) as tel:
        tel.record("setup", 0.0, setup)
        for k in range(2):
            t = 0.1 * k
            cycle = {"t_s": t, "flange2base": EYE, "tool2base": EYE, "fault": "", "s_mm": 0.0, "valid": True,
                     "reason": "", "halt": "", "arc_held": False}
            cycle.update(cycle_change or {})
            tel.record("cycle", t, cycle)
            tel.image(t, np.zeros((8, 10), np.uint8))


def test_an_intact_recording_reads_back(tmp_path):
    _write(tmp_path / "r.mcap")
    rec = read_recording(tmp_path / "r.mcap")
    assert len(rec.frames) == 2 and np.array_equal(rec.cam2flange, np.eye(4)) and rec.seed_px is None
    assert np.array_equal(rec.teach.taught_mm, [500.0, 0.0, 100.0]) and rec.frames[1].t_s == 0.1


@pytest.mark.parametrize("setup, cycle, says", [
    ({"cam2flange": [float("nan")] * 16}, None, "cam2flange is not a finite number"),
    ({"cam2flange": EYE[:12]}, None, "cam2flange is not a list of 16 numbers"),
    ({"cam2flange": (2 * np.eye(4)).ravel().tolist()}, None, "the recorded cam2flange is not a rigid transform"),
    ({"seed_px": [1.0, 2.0, 3.0]}, None, "seed_px is not a list of 2 numbers"),
    ({"taught_mm": [1.0, 2.0]}, None, "taught_mm is not a list of 3 numbers"),
    ({"travel": [2.0, 0.0, 0.0]}, None, "direction of travel is not a unit vector"),
    ({"travel": "x"}, None, "travel is not a list of 3 numbers"),
    (None, {"flange2base": [0.0] * 16}, "flange2base is not a rigid transform"),
    (None, {"tool2base": [True] * 16}, "tool2base is not a finite number"),
    (None, {"t_s": "soon"}, "t_s is not a finite number"),
])
def test_a_damaged_record_is_named(tmp_path, capsys, setup, cycle, says):
    path = tmp_path / "r.mcap"
    _write(path, setup, cycle)
    with pytest.raises(ValueError, match=says):
        read_recording(path)
    assert main(["replay", str(path), "--rig", "default"]) == 2
    err = capsys.readouterr().err
    assert says in err and len(err.strip().splitlines()) == 1, err


def test_a_cut_file_says_it_is_damaged_or_cut_short(tmp_path, capsys):
    path = tmp_path / "r.mcap"
    _write(path)
    data = path.read_bytes()
    path.write_bytes(data[:len(data) * 2 // 3])
    assert main(["replay", str(path), "--rig", "default"]) == 2
    err = capsys.readouterr().err
    assert "the file is damaged or cut short" in err and len(err.strip().splitlines()) == 1, err


@pytest.mark.parametrize("rig, says", [("default", "640x480"), ("mv1440", "1440x1080")])
def test_a_recording_of_another_camera_is_named(tmp_path, capsys, rig, says):
    """Frames another camera recorded (10 px wide here): named with the rig's camera (a trial: replay of a
    default-rig run through mv1440 said "image is 640x32 px but the camera is 1440x34 px", its sensor window)."""
    path = tmp_path / "r.mcap"
    _write(path)
    assert main(["replay", str(path), "--rig", rig]) == 2
    err = capsys.readouterr().err
    assert f"its frames are 10 px wide but the rig's camera is {says} px: replay it with the rig the run was " \
           "recorded with" in err and len(err.strip().splitlines()) == 1, err
