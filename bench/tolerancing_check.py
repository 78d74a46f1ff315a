"""Issue 29's acceptance study, run on demand (minutes, not in the suite): a Monte-Carlo study's 3-D error
distribution against builds of the same tolerances calibrated one by one with the command line, and its
sensitivity ranking against ``psvs design --tolerance``'s order for the row offset (docs/tolerancing.md).

    python bench/tolerancing_check.py STUDY_DIR [K]

STUDY_DIR: a finished ``psvs montecarlo --rig default --tolerances default`` folder. K (default 16) other builds
of the same tolerances (seed 4242, independent of the study's) are each written as a rig file, rendered with
``psvs card-views --views 16`` and calibrated with ``psvs calibrate`` from the default rig, two at a time; each
calibrated rig is scored as the study scores its samples (3-D error after the rigid motion on the same test
points). Prints both distributions, a two-sample Kolmogorov-Smirnov test, and the rankings.
"""
from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SEED = 4242


def _psvs(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "psvs", *args], check=True, capture_output=True, text=True,
                   env={"PYTHONPATH": str(ROOT / "src"), "MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin",
                        "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"})


def one_by_one(index: int) -> float:
    """Build ``index`` of seed 4242 calibrated through the command line; its 3-D RMS error after the rigid
    motion (mm), NaN when calibrate refuses it."""
    from psvs.io.params import dumps_rig, load_rig
    from psvs.study.build import draw_build, views_seed
    from psvs.study.sample import reconstruction_errors, scoring_points_mm
    from psvs.study.tolerances import load_tolerances
    nominal, tol = load_rig("default"), load_tolerances("default")
    build, _ = draw_build(nominal, tol, SEED, index)
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        (t / "build.toml").write_text(dumps_rig(build))
        _psvs("card-views", str(t / "cards"), "--rig", str(t / "build.toml"), "--views", str(tol.procedure.views),
              "--seed", str(views_seed(SEED, index)))
        try:
            _psvs("calibrate", str(t / "cards"), "--rig", "default", "-o", str(t / "cal.toml"))
        except subprocess.CalledProcessError:
            return float("nan")
        cal = load_rig(str(t / "cal.toml"))
    return reconstruction_errors(cal, build, scoring_points_mm(nominal, tol.test))["rms_3d_mm"]


def main(study: Path, k: int) -> None:
    import pyarrow.parquet as pq
    from scipy.stats import ks_2samp
    rows = pq.read_table(study / "results.parquet").to_pylist()
    mc = np.array([r["rms_3d_mm"] for r in rows if r["ok"]])
    with ThreadPoolExecutor(2) as ex:
        alone = np.array(list(ex.map(one_by_one, range(k))))
    ok = alone[np.isfinite(alone)]
    pct = lambda x: np.percentile(x, [10, 50, 90]).round(3).tolist()  # noqa: E731
    print(f"study: {len(mc)} of {len(rows)} builds calibrated; 3-D RMS after the rigid motion p10/50/90 {pct(mc)} mm")
    print(f"one by one (psvs card-views + psvs calibrate, seed {SEED}): {len(ok)} of {k} calibrated; {pct(ok)} mm")
    print(f"two-sample Kolmogorov-Smirnov: D = {ks_2samp(mc, ok).statistic:.3f}, p = {ks_2samp(mc, ok).pvalue:.3f}")
    scores = json.loads((study / "scores.json").read_text())
    for method in ("rss_sensitivity", "sensitivity"):
        rank = scores[method].get("row_offset_px")
        print(f"{method} for row_offset_px: {json.dumps(rank)[:600]}")


if __name__ == "__main__":
    main(Path(sys.argv[1]), int(sys.argv[2]) if len(sys.argv) > 2 else 16)
