"""psvs card-views never mixes a new set of views with other files (issue 41 item 4): an earlier set of
card views (card_NN.png, target.toml) is replaced whole; a folder holding anything else is refused."""
import hashlib

from tests.support.cli import run


def _digests(folder) -> dict:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())}


def test_a_new_set_replaces_an_earlier_one_whole(capsys, tmp_path):
    """Six views of the misaligned build, then three through the default rig into the same folder: the
    folder holds exactly the three new views and their target (card_03..05 of the first set gone), byte for
    byte what the second command writes into a new folder; nothing of the work is left beside it."""
    cards = tmp_path / "cards"
    assert run(capsys, "card-views", str(cards), "--rig", "misaligned", "--views", "6")[0] == 0
    assert len(list(cards.glob("card_*.png"))) == 6
    assert run(capsys, "card-views", str(cards), "--rig", "default", "--views", "3", "--seed", "5")[0] == 0
    fresh = tmp_path / "fresh"
    assert run(capsys, "card-views", str(fresh), "--rig", "default", "--views", "3", "--seed", "5")[0] == 0
    assert _digests(cards) == _digests(fresh)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cards", "fresh"]


def test_a_folder_with_other_files_is_refused_and_kept(capsys, tmp_path):
    cards = tmp_path / "views"
    cards.mkdir()
    (cards / "view_00.png").write_bytes(b"a capture's view")
    (cards / "card_00.png").write_bytes(b"an older card view")
    code, _, err = run(capsys, "card-views", str(cards), "--rig", "default", "--views", "3")
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert f"{cards} holds files card-views did not write (view_00.png): a calibration reads every image" in err
    assert _digests(cards) == {"card_00.png": hashlib.sha256(b"an older card view").hexdigest(),
                               "view_00.png": hashlib.sha256(b"a capture's view").hexdigest()}
