"""Calibration from a robot sweep: planted truth (render through a known rig, calibrate from a rough start)."""
import csv

import numpy as np
import pytest

from psvs import default_rig
from psvs.accuracy.table1 import HOLDER, ROBOT_OFFSET_MM, pattern_image, rough_start
from psvs.calibrate.folder import calibrate_folder
from psvs.calibrate.sweep import calibrate_sweep, read_sweep
from psvs.io.images import write_png
from psvs.measure.triangulate import triangulate
from psvs.optics.project import project_points
from psvs.targets.pattern import detect_pattern
from tests.support.cli import EXAMPLE, run

SWEEP = np.arange(450.0, 1151.0, 140.0)   # 6 positions


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sweep")
    rig = default_rig()
    rows = []
    for z in SWEEP:
        name = f"z{z:.0f}.png"
        write_png(folder / name, pattern_image(rig, z, int(z)))
        rows.append((name, z - ROBOT_OFFSET_MM))
    write_png(folder / "blank.png", np.full((480, 640), 30, np.uint8))
    rows.append(("blank.png", 2000.0))
    with (folder / "sweep.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["image", "position_mm"])
        w.writerows(rows)
    return folder


def test_recovers_the_rig_from_a_rough_start(sweep_dir):
    """Start: f 10 % long, b 10 mm long, principal point 3 px off, plate 2 mm. Truth: f 11.3, b 100,
    (319.5, 239.5), plate 3 mm, offset -312.7 mm, pattern turned -3 deg about y."""
    res = calibrate_folder(sweep_dir, rough_start(default_rig()))
    b = res.bundle
    v, s = b.values, b.sigma
    assert b.success and b.rms_px < 0.1
    assert res.skipped.keys() == {"blank.png"} and "image is blank" in res.skipped["blank.png"]
    assert len(res.used) == len(SWEEP) and set(res.used.values()) == {"sweep"}
    assert abs(v["focal_length_mm"] - 11.3) < 0.01
    assert abs(res.baseline_mm - 100.0) < 0.5 and res.baseline_sigma_mm < 0.5
    # what the sweep saw -- the pattern's row, 450-1150 mm -- the calibrated rig measures: true
    # correspondences of points there triangulate within 0.5 mm, the bound for a sweep alone (the
    # whole field needs card views; absolute depth rests on the design, since the robot's offset is free)
    zz, xx = np.meshgrid(np.linspace(450.0, 1150.0, 8), np.linspace(-40.0, 50.0, 7))
    pts = np.column_stack([xx.ravel(), np.full(xx.size, -4.0), zz.ravel()])
    left, _ = project_points(pts, default_rig(), "left")
    right, _ = project_points(pts, default_rig(), "right")
    got = triangulate(left, right, b.rig, model="exact").points_mm
    assert np.mean(np.linalg.norm(got - pts, axis=1)) < 0.5
    assert abs(b.sweep["offset_mm"] - ROBOT_OFFSET_MM) < 1.0
    assert abs(b.sweep["ry_rad"] - np.radians(HOLDER["tilt_y_deg"])) < 0.01
    assert all(np.isfinite(x) and x >= 0 for x in s.values())
    assert s["focal_length_mm"] < 0.01
    # five circles in a row cannot show the lens's higher terms: they stay at the start, said so
    assert {"k2", "k3", "m4_tilt_a_rad"} <= set(b.held_by_prior)


def test_calibrate_cli(capsys, tmp_path, sweep_dir):
    """The rig file it writes reads back (tomllib, then load_rig) with the values it printed."""
    import re
    import tomllib

    from psvs.io.params import load_rig
    out = tmp_path / "cal.toml"
    code, text, err = run(capsys, "calibrate", str(sweep_dir), "--rig", EXAMPLE, "-o", str(out))
    assert code == 0 and "skipped blank.png: image is blank" in err
    printed = {m[0]: float(m[1]) for m in re.findall(r"^  (\w+)\s+(-?[0-9.]+)  \+-", text, re.M)}
    data = tomllib.loads(out.read_text())
    rig = load_rig(out)
    assert data["camera"]["focal_length_mm"] == pytest.approx(printed["focal_length_mm"], abs=1e-5)
    assert rig.camera.focal_length_mm == pytest.approx(printed["focal_length_mm"], abs=1e-5)
    assert rig.camera.principal_point_px == pytest.approx((printed["cx_px"], printed["cy_px"]), abs=1e-5)
    assert rig.mirrors.plate_thickness_mm == pytest.approx(printed["plate_thickness_mm"], abs=1e-5)
    assert np.degrees(rig.mirrors.error("m1").tilt_rad[0]) == pytest.approx(printed["m1_tilt_a_deg"], abs=1e-5)
    assert rig.mirrors.error("m4").shift_mm == pytest.approx(printed["m4_shift_mm"], abs=1e-5)
    held = re.search(r"parameter\(s\) held near nominal by their priors \((.*)\)", text)[1]
    assert {"k2 +-0.5", "p1 +-0.02", "m4_tilt_a_deg +-0.3", "box_z_deg +-0.3"} <= set(held.split(", "))
    # a term held at the design outright is printed with its prior's 1-sigma, not 0 (an adversarial trial)
    sigma = {m[0]: float(m[1]) for m in re.findall(r"^  (\w+)\s+-?[0-9.]+  \+- ([0-9.]+)  \(not seen", text, re.M)}
    assert sigma["k2"] == 0.5 and sigma["p1"] == 0.02 and all(v > 0 for v in sigma.values())


def test_bad_sweeps(capsys, tmp_path, sweep_dir):
    code, _, err = run(capsys, "calibrate", str(tmp_path), "--rig", EXAMPLE, "-o", str(tmp_path / "r.toml"))
    assert code == 2 and "holds neither target.toml (hand-held card views) nor sweep.csv" in err
    (tmp_path / "sweep.csv").write_text("file,z\na.png,3\n")
    with pytest.raises(ValueError, match="expected columns image,position_mm"):
        read_sweep(tmp_path)
    (tmp_path / "sweep.csv").write_text("image,position_mm\na.png,far\n")
    with pytest.raises(ValueError, match="position_mm is not a number: 'far'"):
        read_sweep(tmp_path)
    for bad in ("nan", "inf"):        # SciPy's "initial guess is outside of provided bounds" before
        (tmp_path / "sweep.csv").write_text(f"image,position_mm\na.png,700\nb.png,{bad}\n")
        with pytest.raises(ValueError, match=rf"sweep\.csv:3: position_mm must be a finite robot reading \(mm\), "
                                             rf"got '{bad}'"):
            read_sweep(tmp_path)
    obs = [("a", 700.0, detect_pattern(pattern_image(default_rig(), 400.0 - ROBOT_OFFSET_MM + ROBOT_OFFSET_MM, 1)))]
    with pytest.raises(ValueError, match="needs at least 3 usable sweep images, got 1"):
        calibrate_sweep(obs, default_rig())


def test_a_sweep_that_repeats_an_image_or_a_position_is_refused(tmp_path, sweep_dir):
    """One image listed four times (it calibrated, 'used 1 image(s)', and wrote a rig), one robot position
    for two images, and one image copied under another name: refused before any work, naming them."""
    import shutil
    names = sorted(p.name for p in sweep_dir.glob("z*.png"))
    for name in names:
        shutil.copy(sweep_dir / name, tmp_path / name)
    rows = lambda pairs: "image,position_mm\n" + "".join(f"{n},{z}\n" for n, z in pairs)  # noqa: E731
    (tmp_path / "sweep.csv").write_text(rows([(names[0], 700 + k) for k in range(4)]))
    with pytest.raises(ValueError, match=f"sweep.csv lists {names[0]} 4 times: each row must be its own image"):
        read_sweep(tmp_path)
    (tmp_path / "sweep.csv").write_text(rows([(names[0], 700), (f"./{names[0]}", 710), (names[1], 720)]))
    with pytest.raises(ValueError, match=f"lists {names[0]} 2 times"):          # the same file by another path
        read_sweep(tmp_path)
    (tmp_path / "sweep.csv").write_text(rows([(names[0], 700), (names[1], 700.0), (names[2], 720)]))
    with pytest.raises(ValueError, match=f"sweep.csv lists robot position 700 mm for 2 images \\({names[0]}, "
                                         f"{names[1]}\\): each sweep image must be at its own position"):
        read_sweep(tmp_path)
    shutil.copy(tmp_path / names[0], tmp_path / "copy.png")
    (tmp_path / "sweep.csv").write_text(rows([(names[0], 700), ("copy.png", 710), (names[2], 720)]))
    with pytest.raises(ValueError, match=f"{names[0]} and copy.png are the same image \\(byte-identical files\\)"):
        calibrate_folder(tmp_path, default_rig())
    obs = [("a", 700.0, None), ("b", 700.0, None), ("c", 720.0, None)]
    with pytest.raises(ValueError, match=r"the sweep lists robot position 700 mm for 2 images \(a, b\)"):
        calibrate_sweep(obs, default_rig())
