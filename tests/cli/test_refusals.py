"""A measurement is right or says it is not: well-formed input that cannot give a right answer is refused
in one line ("cannot measure: ...", exit status 1) with nothing written; rows that no scene point can give
are marked invalid. Planted truth throughout."""
import numpy as np

from psvs import default_rig
from psvs.optics.project import project_points
from tests.cli.test_cli import EXAMPLE, run


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
        assert got[:, 3].tolist() == [1, 1, 1, 0, 0, 0] and np.isnan(got[3:, :3]).all()
        assert np.abs(got[:3, 2] - pts[:3, 2]).max() < (1e-6 if model == "exact" else 15.0)
