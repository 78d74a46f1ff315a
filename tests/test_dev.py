"""dev.py, the quickstart's launcher: psvs runs in the caller's folder."""
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_dev_psvs_writes_relative_outputs_where_the_user_is(tmp_path):
    rig = ROOT / "examples" / "rigs" / "default.toml"
    proc = subprocess.run([sys.executable, str(ROOT / "dev.py"), "psvs", "design", "--rig", str(rig),
                           "-o", "mirrors_from_elsewhere.json"], cwd=tmp_path, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    table = json.loads((tmp_path / "mirrors_from_elsewhere.json").read_text())
    assert [m["name"] for m in table["mirrors"]] == ["M1", "M2", "M3", "M4"] and table["checks"]["ok"] is True
    assert not (ROOT / "mirrors_from_elsewhere.json").exists()
