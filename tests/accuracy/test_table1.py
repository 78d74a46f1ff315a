"""The paper's experiment end to end (the acceptance figures, on our own renders)."""
import pytest

from tests.support.cli import run

#: long end-to-end runs: the README's test command runs them; .ci/latest (newest releases) does not
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def table1(tmp_path_factory):
    from psvs import default_rig
    from psvs.accuracy.table1 import run_table1, write_outputs
    t = run_table1(default_rig())
    out = tmp_path_factory.mktemp("t1")
    return t, write_outputs(out, t)


def test_ten_times_better_than_the_paper(table1):
    """The acceptance figures: mean |Z error| <= 0.25 mm, max <= 0.6 mm; diameter error <= 0.03 mm mean;
    first-last distance error <= 0.1 mm mean (the paper: 2.50, 8.61, 0.145 and 0.72 mm)."""
    t, _ = table1
    s = t.summary()["ours"]
    assert s["mean_abs_z_error_mm"] <= 0.25 and s["max_abs_z_error_mm"] <= 0.6
    assert s["mean_distance_error_mm"] <= 0.1
    assert s["mean_diameter_error_mm"] <= 0.03
    assert t.summary()["paper"]["mean_abs_z_error_mm"] == pytest.approx(2.50, abs=0.01)


def test_outputs_read_back_by_value(table1):
    """table1.csv (csv module), table1.md (its Markdown rows) and fig10.png (OpenCV) hold what was measured."""
    import csv as csvlib

    import cv2
    import numpy as np

    from psvs.accuracy.table1 import PAPER_TABLE1
    t, files = table1
    csv, md, fig = files
    rows = list(csvlib.DictReader(csv.open()))
    ours = np.array([[float(r[k]) for k in ("Z_meas_mm", "Z_calc_mm", "d_calc_mm", "a_calc_mm")] for r in rows])
    assert ours == pytest.approx(t.rows(), abs=5.1e-5)                        # 4 decimals
    paper = np.array([[float(r[k]) for k in ("Z_calc_paper_mm", "d_calc_paper_mm", "a_calc_paper_mm")] for r in rows])
    assert paper == pytest.approx(PAPER_TABLE1[:, 1:], abs=5.1e-5)
    table = [ln.strip("|").split("|") for ln in md.read_text().splitlines() if ln.startswith("| ") and
             ln[2].isdigit()]
    assert np.array([[float(c) for c in r] for r in table])[:, [0, 2, 4, 6]] == pytest.approx(t.rows(), abs=5e-4)
    s = t.summary()
    assert f"| mean \\|Z error\\| (mm) | 2.500 | {s['ours']['mean_abs_z_error_mm']:.3f} |" in md.read_text()
    img = cv2.imread(str(fig))
    assert img.shape == (420, 1100, 3) and img.std() > 10                    # 11 x 4.2 in at 100 dpi


def test_cli_help_and_bad_output(capsys, tmp_path):
    code, out, _ = run(capsys, "table1", "--help")
    assert code == 0 and "Table I" in out
    f = tmp_path / "f.txt"
    f.write_text("keep")
    code, _, err = run(capsys, "table1", "-o", str(f))
    assert code == 2 and "is a file" in err and f.read_text() == "keep"


def test_table1_on_a_misaligned_build_from_the_sweep_alone():
    """A build from the sweep alone: the paper's robot sweep through examples/rigs/misaligned.toml,
    calibrated from its design (examples/rigs/clear.toml): mean |Z error| <= 0.5 mm on the 15 test
    distances, first-last distance within 0.1 mm, diameters within 0.03 mm."""
    from pathlib import Path

    from psvs.accuracy.table1 import run_table1
    from psvs.io.params import load_rig
    rigs = Path(__file__).resolve().parents[2] / "examples" / "rigs"
    design = load_rig(rigs / "clear.toml").with_extents({k: None for k in ("m1", "m2", "m3", "m4")})
    t = run_table1(load_rig(rigs / "misaligned.toml"), start=design, method="sweep")
    s = t.summary()["ours"]
    assert t.calibration.rms_px < 0.05
    assert s["mean_abs_z_error_mm"] <= 0.5 and s["mean_distance_error_mm"] <= 0.1
    assert s["mean_diameter_error_mm"] <= 0.03      # rims paired along epipolar curves (they were NaN)
