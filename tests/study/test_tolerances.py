"""TOL.toml: the shipped example reads to the values it states, groups and their overrides, and every bad entry
is refused in one line naming the file and the key (corpus style)."""
import math

import pytest

from psvs.study.tolerances import GROUPS, PARAMS, Dist, load_tolerances, tolerances_from_dict


def test_shipped_default_reads_as_written():
    """The shipped file: mirrors +-0.2 deg (both tilts of all four), +-0.5 mm, 16 card views."""
    tol = load_tolerances("default")
    for k in range(1, 5):
        for a in "ab":
            assert tol.dists[f"m{k}_tilt_{a}_deg"] == Dist("uniform", math.radians(0.2))
        assert tol.dists[f"m{k}_shift_mm"] == Dist("uniform", 0.5)
    assert tol.dists["cx_px"] == tol.dists["cy_px"] == Dist("normal", 5.0)
    assert "k2" not in tol.dists
    p = tol.procedure
    assert (p.views, p.near_mm, p.far_mm, p.tilt_deg, p.supersample) == (16, 450.0, 1000.0, 25.0, 2)
    assert (p.card.rows, p.card.cols, p.card.spacing_mm, p.card.diameter_mm) == (4, 6, 14.0, 7.0)
    assert tol.targets["rms_3d_mm"] == 0.5 and tol.test.table1 is False


def test_an_individual_key_overrides_its_group_and_an_empty_file_tolerances_nothing():
    tol = tolerances_from_dict({"tolerances": {"mirror_tilt_deg": {"normal": 0.1},
                                               "m2_tilt_b_deg": {"uniform": 1.0}}})
    assert tol.dists["m2_tilt_b_deg"] == Dist("uniform", math.radians(1.0))
    assert tol.dists["m2_tilt_a_deg"] == Dist("normal", math.radians(0.1))
    assert set(tol.dists) == set(GROUPS["mirror_tilt_deg"])
    assert list(tol.dists) == [k for k in PARAMS if k in tol.dists]     # draw order, whatever the file's
    assert tolerances_from_dict({}).dists == {}


BAD = [
    ("[tolerance]\n", "unknown table [tolerance]"),
    ("[tolerances]\nmirror_tilt = { uniform = 0.2 }\n", "unknown key tolerances.mirror_tilt"),
    ("[tolerances]\nk1 = 0.05\n", "tolerances.k1 must be { uniform = HALF_WIDTH } or { normal = SIGMA }"),
    ("[tolerances]\nk1 = { gauss = 0.05 }\n", "tolerances.k1 must be"),
    ("[tolerances]\nk1 = { uniform = 0.1, normal = 0.1 }\n", "tolerances.k1 must be"),
    ("[tolerances]\nm1_shift_mm = { uniform = -0.5 }\n", "tolerances.m1_shift_mm.uniform must be >= 0"),
    ("[tolerances]\nm1_shift_mm = { uniform = nan }\n", "tolerances.m1_shift_mm.uniform must be a finite number"),
    ("[tolerances]\nsplit_ratio = { normal = \"5\" }\n", "tolerances.split_ratio.normal must be a finite number"),
    ("[calibration]\nviews = 2\n", "calibration.views must be a whole number 3-60"),
    ("[calibration]\nviews = 16.0\n", "calibration.views must be a whole number"),
    ("[calibration]\nnear_mm = 900\nfar_mm = 500\n", "calibration.far_mm must be > calibration.near_mm"),
    ("[calibration]\ntilt_deg = 80\n", "calibration.tilt_deg must be 0-60"),
    ("[calibration]\nsupersample = 9\n", "calibration.supersample must be a whole number 1-4"),
    ("[calibration]\nread_noise_e = -1\n", "calibration.read_noise_e must be >= 0"),
    ("[calibration]\ncard = { rows = 4, cols = 6, pitch_mm = 14 }\n", "unknown key calibration.card.pitch_mm"),
    ("[calibration]\ncard = { diameter_mm = 0 }\n", "calibration.card.diameter_mm must be > 0"),
    ("[calibration]\ncard = { spacing_mm = 5, diameter_mm = 7 }\n", "calibration.card:"),
    ("[calibration]\nrobot = true\n", "unknown key calibration.robot"),
    ("[test]\ntable1 = 1\n", "test.table1 must be true or false"),
    ("[calibration]\ninterleave = \"yes\"\n", "calibration.interleave must be true or false"),
    ("[calibration]\nmethod = \"robot\"\n", "calibration.method must be one of card, sweep"),
    ("[calibration]\nsweep = { from_mm = 425, to_mm = 500, step_mm = 50 }\n", "calibration.sweep has 2 positions"),
    ("[calibration]\nsweep = { from_mm = 900, to_mm = 500 }\n", "calibration.sweep.to_mm must be >="),
    ("[calibration]\nsweep = { start_mm = 400 }\n", "unknown key calibration.sweep.start_mm"),
    ("[test]\ngrid = 1\n", "test.grid must be a whole number 2-50"),
    ("[targets]\nrms_mm = 1\n", "unknown key targets.rms_mm"),
    ("[targets]\nrms_3d_mm = 0\n", "targets.rms_3d_mm must be > 0"),
    ("[calibration\nviews = 3\n", "malformed TOML"),
    ("tolerances = 3\n", "[tolerances] must be a table"),
]


@pytest.mark.parametrize("text,message", BAD, ids=[b[1][:40] for b in BAD])
def test_bad_tol_files_are_refused_in_one_line(tmp_path, text, message):
    path = tmp_path / "tol.toml"
    path.write_text(text)
    with pytest.raises(ValueError) as info:
        load_tolerances(path)
    text = str(info.value)
    assert message in text and str(path) in text and "\n" not in text


def test_tolerances_pickle_for_the_workers():
    """A runner ships the tolerances to other processes: they pickle and come back equal."""
    import pickle
    tol = load_tolerances("default")
    assert pickle.loads(pickle.dumps(tol)) == tol


def test_a_missing_file_is_named(tmp_path):
    with pytest.raises(FileNotFoundError, match="tolerances file not found: .*nope.toml"):
        load_tolerances(tmp_path / "nope.toml")


def test_the_documented_file_is_the_shipped_one():
    """docs/tolerancing.md's TOML block reads to the same Tolerances as the shipped file."""
    import re
    import tomllib
    from pathlib import Path
    text = (Path(__file__).resolve().parents[2] / "docs" / "tolerancing.md").read_text(encoding="utf-8")
    block = re.search(r"```toml\n(.*?)```", text, re.S).group(1)
    assert tolerances_from_dict(tomllib.loads(block)) == load_tolerances("default")
