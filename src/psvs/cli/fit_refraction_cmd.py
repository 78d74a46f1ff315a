"""``psvs fit-refraction``: fit l and m of eq. (15) to matches of known points; write them into a rig file."""
from __future__ import annotations

import numpy as np

from psvs.cli.common import add_rig_argument, check_distinct, check_output_path, measuring_rig
from psvs.io.params import save_rig
from psvs.io.points import MATCH_COLUMNS, read_csv_columns
from psvs.measure.refraction_fit import fit_refraction
from psvs.measure.triangulate import triangulate
from psvs.optics.plate import derived_refraction_terms

TRUTH_COLUMNS = ("X_mm", "Y_mm", "Z_mm")


def add_parser(sub) -> None:
    p = sub.add_parser("fit-refraction", help="fit l, m of eq. (15) to matched pixels of known points",
                       description="Fit the refraction terms l, m of eq. (15) by least squares in depth. Input "
                                   "CSV columns u_l,v_l,u_r,v_r (px) and X_mm,Y_mm,Z_mm (the known points). "
                                   "Refused (exit 1, nothing written) when the points cannot pin l and m (fewer "
                                   "than 3 distinct points, an ill-conditioned fit) or disagree with eq. (15) "
                                   "beyond a 0.3 px disparity error, or their X, Y lie off their pixels "
                                   "(eqs. 16-17) beyond it; a point not in front of the rig or a non-finite "
                                   "value is bad input (exit 2).")
    add_rig_argument(p)
    p.add_argument("points", metavar="MATCHES.csv", help="CSV with u_l,v_l,u_r,v_r,X_mm,Y_mm,Z_mm")
    p.add_argument("-o", "--output", metavar="RIG.toml", help="write the rig with refraction_l_mm/_m_mm set")
    p.set_defaults(run=run)


def run(args) -> int:
    out = check_output_path(args.output, (".toml", ".json"))
    check_distinct({"-o": args.output}, {"MATCHES.csv": args.points, "--rig": args.rig})
    rig = measuring_rig(args.rig)
    data = read_csv_columns(args.points, MATCH_COLUMNS + TRUTH_COLUMNS)
    left, right, pts = data[:, :2], data[:, 2:4], data[:, 4:]
    fit = fit_refraction(left, right, pts, rig)
    fitted = rig.replace(refraction_l_mm=fit.l_mm, refraction_m_mm=fit.m_mm)
    res = triangulate(left, right, fitted, model="refraction")
    err = np.linalg.norm(res.points_mm[res.valid] - pts[res.valid], axis=1)
    l_der, m_der = derived_refraction_terms(rig)
    print(f"l = {fit.l_mm:.6f} mm, m = {fit.m_mm:.6f} mm (derived from d, n, omega_1: l = {l_der:.6f}, "
          f"m = {m_der:.6f})")
    print(f"fit on {fit.n_rows} points: RMS depth residual {fit.rms_residual_mm:.4f} mm (a 0.3 px disparity "
          f"error: {fit.noise_rms_mm:.4f} mm), condition number {fit.condition:.3g} (limit {fit.condition_limit:.3g})")
    if err.size:
        print(f"{err.size} points seen by the refraction model: mean 3-D error {err.mean():.4f} mm, "
              f"max {err.max():.4f} mm")
    if out is not None:
        save_rig(fitted, out)
    return 0
