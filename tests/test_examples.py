"""The example scripts (examples/plot_*.py) run headless and draw their figure (STYLE.md section 9)."""
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = sorted((ROOT / "examples").glob("plot_*.py"))


@pytest.mark.parametrize("script", SCRIPTS, ids=[s.stem for s in SCRIPTS])
def test_example_draws_its_figure(script, tmp_path):
    out = tmp_path / "figure.png"
    proc = subprocess.run([sys.executable, str(script), str(out)], capture_output=True, text=True, timeout=300,
                          env={"MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin", "PYTHONPATH": str(ROOT / "src"),
                               "PSVS_CACHE_DIR": os.environ["PSVS_CACHE_DIR"]})   # the session's (conftest.py)
    assert proc.returncode == 0, proc.stderr
    img = cv2.imread(str(out))
    assert img is not None and min(img.shape[:2]) >= 300
    assert (np.abs(img.astype(int) - 255).sum(axis=2) > 60).mean() > 0.05
