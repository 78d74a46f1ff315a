"""`psvs track`'s output folder and a seam never seen (trial 44): a run replaces an earlier run's files whole
(its bag too, when the new run writes none), never a user's own; a seed off the groove is no weld."""
import json

import pytest

from psvs.cli.main import main
from tests.support.cli import run


@pytest.fixture(scope="module")
def handeye(tmp_path_factory):
    he = tmp_path_factory.mktemp("he") / "he.toml"
    assert main(["handeye", "--rig", "default", "-o", str(he)]) == 0
    return str(he)


def _track(capsys, handeye, out, *extra):
    return run(capsys, "track", "weld_seam", "--rig", "default", "--handeye", handeye, "--length", "3", "-o", str(out),
               *extra)


def test_a_run_replaces_an_earlier_runs_bag_and_never_a_users_file(capsys, tmp_path, handeye):
    """Run A writes its bag; run B into the same folder with --no-bag leaves none of A's behind (it left A's
    bag beside B's report). A folder holding a file no run writes, or a log.csv without a run's report, is
    refused before any work, and its files are as they were."""
    out = tmp_path / "run"
    code, _, err = _track(capsys, handeye, out)
    assert code == 0, err
    assert (out / "bag").is_dir()
    code, _, err = _track(capsys, handeye, out, "--no-bag", "--speed", "20")
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == ["error.png", "log.csv", "report.json", "top_view.png"]
    assert json.loads((out / "report.json").read_text())["config"]["speed_mm_s"] == 20.0
    for name in ("log.csv", "notes.txt"):
        mine = tmp_path / f"mine_{name}"
        mine.mkdir()
        (mine / name).write_text("my own data\n")
        code, text, err = _track(capsys, handeye, mine, "--no-bag")
        assert code == 2 and text == "" and err.count("\n") == 1, err
        assert err == (f"psvs track: error: output folder {mine} holds what no track run writes ({name}): give a new "
                       "folder, or an earlier run's\n")
        assert [p.name for p in mine.iterdir()] == [name] and (mine / name).read_text() == "my own data\n"


def test_a_seam_never_seen_is_no_weld(capsys, tmp_path, handeye):
    """A seed in the corner of the window, off the groove: the run saw no seam at all. It exited 0 as if a gap
    had stopped it; now exit 1, its last line saying the seam was never seen, near which seed."""
    code, text, err = _track(capsys, handeye, tmp_path / "r", "--no-bag", "--seed", "1,1")
    assert code == 1, (text, err)
    assert err.strip().splitlines()[-1] == ("psvs track: cannot measure: the seam was never seen: no groove edge near "
                                            "the seed (1, 1) in any sensor frame (the seed off the groove, or the "
                                            "workpiece out of the window?)")
