"""A measurement is right or says it is not: well-formed input that cannot give a right answer is refused
in one line ("cannot measure: ...", exit status 1) with nothing written; rows that no scene point can give
are marked invalid. Planted truth throughout."""
import numpy as np
import pytest

from psvs import default_rig
from psvs.optics.project import project_points
from tests.support.cli import EXAMPLE, run


def write_csv(path, header, rows):
    path.write_text(",".join(header) + "\n" + "".join(",".join(repr(float(v)) for v in r) + "\n" for r in rows))
    return path


def test_triangulate_marks_rows_no_point_can_give(capsys, tmp_path):
    """Planted points through the default rig, then: one pixel moved off the sensor, one pair swapped
    (left for right), one disparity made negative. Those rows: NaN, valid 0; the others: the truth."""
    rig = default_rig()
    pts = np.array([[0.0, 0.0, 500.0], [30.0, -20.0, 800.0], [-60.0, 40.0, 1100.0], [10.0, 10.0, 600.0],
                    [-20.0, 5.0, 700.0], [25.0, -15.0, 900.0]])
    left, _ = project_points(pts, rig, "left")
    right, _ = project_points(pts, rig, "right")
    left[3, 0] = 640.2                                  # off the sensor (u > W - 0.5)
    left[4], right[4] = right[4].copy(), left[4].copy()   # swapped: the rays diverge
    right[5, 0] = left[5, 0] + 3.0                      # negative disparity
    csv = write_csv(tmp_path / "m.csv", ("u_l", "v_l", "u_r", "v_r"), np.column_stack([left, right]))
    out = tmp_path / "p.csv"
    for model in ("paper", "refraction", "exact"):
        code, _, err = run(capsys, "triangulate", "--rig", EXAMPLE, str(csv), "--model", model, "-o", str(out))
        assert code == 0 and f"3 of 6 points valid ({model} model)" in err
        got = np.loadtxt(out, delimiter=",", skiprows=1)
        assert got[:, 4].tolist() == [1, 1, 1, 0, 0, 0] and np.isnan(got[3:, :4]).all()   # X, Y, Z, Z_sigma_mm, valid
        assert np.abs(got[:3, 2] - pts[:3, 2]).max() < (1e-6 if model == "exact" else 15.0)


FIT_COLUMNS = ("u_l", "v_l", "u_r", "v_r", "X_mm", "Y_mm", "Z_mm")


def test_fit_refraction_refuses_what_the_points_cannot_pin(capsys, tmp_path):
    """README's example fits and writes the rig; six copies of one of its points, one point 40 mm off in
    Z, and points along the optical axis are refused in one line (exit 1) and the earlier rig file is kept;
    a point behind the rig is bad input (exit 2)."""
    from tests.support.geometry import EXAMPLES
    rig_file = str(EXAMPLES / "rigs" / "clear.toml")
    data = np.loadtxt(EXAMPLES / "known_points.csv", delimiter=",", skiprows=1)
    out = tmp_path / "fitted.toml"
    code, text, err = run(capsys, "fit-refraction", "--rig", rig_file, str(EXAMPLES / "known_points.csv"),
                          "-o", str(out))
    assert code == 0, err
    assert "fit on 6 points: RMS depth residual 0.1" in text and "mean 3-D error" in text
    written = out.read_text()
    assert "refraction_l_mm" in written
    wrong = data.copy()
    wrong[2, 6] += 40.0
    from psvs.io.params import load_rig
    axis = np.array([[0.0, 0.0, 500.0], [0.0, 0.0, 650.0], [0.0, 0.0, 800.0], [0.0, 0.0, 1100.0]])
    rig = load_rig(rig_file)
    axis_rows = np.column_stack([project_points(axis, rig, "left")[0], project_points(axis, rig, "right")[0], axis])
    cases = {"copies": (np.tile(data[:1], (6, 1)), "6 rows hold 1 distinct point(s)"),
             "wrong_z": (wrong, "RMS depth residual 14.6 mm is 5.6 times the 2.6 mm RMS"),
             "axis": (axis_rows, "do not pin l and m of eq. (15): the fit's condition number is 9.3")}
    for name, (rows, message) in cases.items():
        csv = write_csv(tmp_path / f"{name}.csv", FIT_COLUMNS, rows)
        code, text, err = run(capsys, "fit-refraction", "--rig", rig_file, str(csv), "-o", str(out))
        assert code == 1 and text == "", (name, err)
        assert err.startswith("psvs fit-refraction: cannot measure: ") and message in err, (name, err)
        assert len(err.strip().splitlines()) == 1 and out.read_text() == written
    behind = data.copy()
    behind[0, 6] = -10.0
    csv = write_csv(tmp_path / "behind.csv", FIT_COLUMNS, behind)
    code, _, err = run(capsys, "fit-refraction", "--rig", rig_file, str(csv), "-o", str(out))
    assert code == 2 and "points_mm row 1: Z = -10 mm is not in front of the rig" in err
    assert out.read_text() == written


@pytest.fixture(scope="module")
def fig9_images(tmp_path_factory):
    """Fig. 9 at 640 mm through the default rig and through the misaligned build, and the first resized."""
    import cv2

    from psvs.io.images import write_png
    from psvs.io.params import load_rig
    from psvs.simulate.builtin import builtin_scene
    from psvs.simulate.render import render
    folder = tmp_path_factory.mktemp("fig9")
    paths = {}
    for name in ("default", "misaligned"):
        paths[name] = folder / f"{name}.png"
        write_png(paths[name], render(builtin_scene("fig9:distance_mm=640"), load_rig(name), seed=7).image)
    paths["small"] = folder / "small.png"
    write_png(paths["small"], cv2.resize(cv2.imread(str(paths["default"]), cv2.IMREAD_GRAYSCALE), (480, 360)))
    return paths


@pytest.mark.parametrize("image, extra, code, message", [
    ("default", ["--json"], 0, None),
    ("small", [], 2, "small.png: image is 480x360 px but the rig's camera is 640x480 px"),
    ("default", ["--count", "3"], 1, "psvs measure: cannot measure: found 10 circles, expected 6 (3 per view)"),
    ("misaligned", [], 1, "psvs measure: cannot measure: no pairing of the 10 circles puts every twin on its "
                          "epipolar curve through this rig within 400-1200 mm"),
    ("default", ["--rig", "misaligned"], 1, "px from the nearest, tolerance 1 px"),
    ("default", ["--diameter-mm", "12"], 1, "the pattern's 12 mm, tolerance 0.61"),
    ("default", ["--spacing-mm", "0"], 2, "--spacing-mm must be > 0 mm"),
    ("default", ["--diameter-mm", "25"], 2, "--diameter-mm (25 mm) must be less than --spacing-mm (20 mm)"),
])
def test_measure_circles_checks_what_it_found(capsys, fig9_images, image, extra, code, message):
    """Good: Table I's columns (exit 0). A resized image is bad input (exit 2); --count 3 on the 5-circle
    pattern, the misaligned build's image through the default rig and the default rig's through the build,
    and a pattern of other circles: one line naming the check, nothing on stdout (exit 1)."""
    import json
    argv = ["measure", "circles", str(fig9_images[image]), "--rig", "default", *extra]
    got, out, err = run(capsys, *argv)
    assert got == code, err
    if code == 0:
        data = json.loads(out)
        assert abs(data["Z_mm"] - 640) < 0.5 and abs(data["diameter_mm"] - 10) < 0.1
    else:
        assert out == "" and len(err.strip().splitlines()) == 1 and message in err, err


def test_calibrate_refuses_a_folder_that_repeats_an_image(capsys, tmp_path):
    """sweep.csv listing one image four times used to calibrate ('images = 1' in the rig written); a card
    folder holding one view twice (a copy under another name) too. Both: one line naming the duplicates,
    exit 2, the earlier rig file kept."""
    from psvs.accuracy.table1 import CARD
    from psvs.io.images import write_png
    from psvs.targets.target_file import dumps_target
    rng = np.random.default_rng(1)
    out = tmp_path / "rig.toml"
    out.write_text("earlier")
    sweep = tmp_path / "sweep"
    sweep.mkdir()
    write_png(sweep / "z700.png", rng.integers(0, 255, (480, 640), dtype=np.uint8))
    (sweep / "sweep.csv").write_text("image,position_mm\n" + "".join(f"z700.png,{700 + 50 * k}\n" for k in range(4)))
    code, text, err = run(capsys, "calibrate", str(sweep), "--rig", "clear", "-o", str(out))
    assert code == 2 and text == "" and len(err.strip().splitlines()) == 1
    assert "psvs calibrate: error: sweep.csv lists z700.png 4 times: each row must be its own image" in err
    cards = tmp_path / "cards"
    cards.mkdir()
    (cards / "target.toml").write_text(dumps_target(CARD))
    for k in range(3):
        write_png(cards / f"card_{k}.png", rng.integers(0, 255, (480, 640), dtype=np.uint8))
    (cards / "card_3.png").write_bytes((cards / "card_1.png").read_bytes())
    code, text, err = run(capsys, "calibrate", str(cards), "--rig", "clear", "-o", str(out))
    assert code == 2 and text == "" and len(err.strip().splitlines()) == 1
    assert "card_1.png and card_3.png are the same image (byte-identical files)" in err
    assert out.read_text() == "earlier"


def test_an_output_may_not_replace_a_file_its_input_folder_feeds(capsys, tmp_path):
    """`calibrate DIR -o DIR/target.toml` (and `handeye DIR -o DIR/target.toml`) would replace the card's
    description by the rig computed from it: exit 2 in one line, the file as it was; a new file in the folder
    (the usual DIR/build.toml) is no input and stays allowed (refused here for another reason: no views)."""
    folder = tmp_path / "views"
    folder.mkdir()
    card = '[target]\nkind = "circle_grid"\nrows = 4\ncols = 6\nspacing_mm = 14.0\ndiameter_mm = 7.0\n'
    (folder / "target.toml").write_text(card)
    for command in ("calibrate", "handeye"):
        code, _, err = run(capsys, command, str(folder), "--rig", "default", "-o", str(folder / "target.toml"))
        assert code == 2 and err.strip() == (f"psvs {command}: error: -o names target.toml of the input folder "
                                             f"{'DIR' if command == 'calibrate' else 'VIEWS_DIR'} ({folder}): it "
                                             "would be overwritten by what was computed from it"), err
    assert (folder / "target.toml").read_text() == card
    code, _, err = run(capsys, "calibrate", str(folder), "--rig", "default", "-o", str(folder / "build.toml"))
    assert code != 0 and "input folder" not in err and not (folder / "build.toml").exists()
