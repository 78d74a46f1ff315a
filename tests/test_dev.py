"""dev.py, the quickstart's launcher: psvs runs in the caller's folder."""
import json
import re
import subprocess
import sys
import tomllib
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


def _names(lock: Path) -> set[str]:
    return {line.split("==")[0].lower() for line in lock.read_text().splitlines()
            if line and not line.startswith("#")}


def _requirement_names(reqs: list[str]) -> set[str]:
    return {re.split(r"[ <>=!;\[]", r)[0].lower() for r in reqs}


def test_the_demo_lock_pins_what_psvs_needs_and_the_dev_lock_its_extras():
    """`python3 dev.py demo` installs requirements.lock only: it pins every dependency of pyproject.toml
    and no package of an extra; requirements-dev.lock (added by `dev.py test`) pins every extra's package
    and nothing of the first; every line is an exact pin."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    core, dev = _names(ROOT / "requirements.lock"), _names(ROOT / "requirements-dev.lock")
    for lock in ("requirements.lock", "requirements-dev.lock"):
        pins = [ln for ln in (ROOT / lock).read_text().splitlines() if ln and not ln.startswith("#")]
        assert all(re.fullmatch(r"[A-Za-z0-9._-]+==[0-9][A-Za-z0-9.+-]*", ln) for ln in pins), lock
    assert _requirement_names(project["dependencies"]) <= core
    extras = _requirement_names([r for reqs in project["optional-dependencies"].values() for r in reqs])
    assert extras <= dev and not core & dev
