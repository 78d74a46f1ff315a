"""An image whose self-check cannot judge and whose pairs all fit any row shows nothing of the rig's rows
(psvs.match.correspondence.rows_unshown): `psvs match` refuses it. An adversarial trial (2026-12-06) flipped
Fig. 5b through the misaligned build upside down (a camera's vertical flip): every edge's twin then stands
rows off, the steep straight edges paired with others at 767-955 mm (the ashtrays stand at 690 and 720 mm),
exit 0. The frame as taken keeps pairs on the rows and is answered."""
import dataclasses

import numpy as np
import pytest

from psvs.health.check import check_frames
from psvs.io.images import write_png
from psvs.io.params import load_rig
from psvs.match.correspondence import match_image, rows_unshown
from psvs.simulate.builtin import builtin_scene
from psvs.simulate.render import render
from tests.support.cli import run

#: mm: the depths of Fig. 5b's two ashtrays (docs/matching.md)
ASHTRAYS_MM = (690.0, 720.0)


@pytest.fixture(scope="module")
def fig5b_build():
    """Fig. 5b through the misaligned build: (the frame as taken, the same frame flipped upside down)."""
    image = render(builtin_scene("fig5b"), load_rig("misaligned"), seed=3).image
    return image, np.ascontiguousarray(image[::-1])


def near_an_ashtray(z_mm: float) -> bool:
    return min(abs(z_mm - a) / a for a in ASHTRAYS_MM) <= 0.02


def test_the_flipped_frame_would_pair_wrongly_and_is_refused(fig5b_build, capsys, tmp_path):
    """Without the rule the matcher pairs the flipped frame's edges at depths no object stands at; its self-check
    cannot judge and no pair fits the rows: the command exits 1 with one line, nothing written."""
    rig = load_rig("misaligned")
    _, flipped = fig5b_build
    res = match_image(flipped, rig)
    check = check_frames([flipped], rig)
    assert res.pairs and res.rows_fit == 0 and check.verdict == "cannot judge", (res.rows, check.verdict)
    assert not all(near_an_ashtray(p.median_z_mm()) for p in res.pairs), [p.median_z_mm() for p in res.pairs]
    assert rows_unshown(res, check).startswith("nothing in the image shows that the rig's rows hold")
    path, out = tmp_path / "flipped.png", tmp_path / "m.json"
    write_png(path, flipped)
    code, stdout, err = run(capsys, "match", str(path), "--rig", "misaligned", "--auto", "-o", str(out))
    assert code == 1 and stdout == "" and err.count("\n") == 1, (code, stdout, err)
    assert err.startswith("psvs match: cannot measure: nothing in the image shows that the rig's rows hold: "
                          "its self-check cannot judge (") and not out.exists(), err


def test_a_seed_on_the_flipped_frame_is_refused_too(fig5b_build):
    """From a seed on a left-view edge of the flipped frame: its pair fits any row, and so do the automatic
    matcher's on the same image."""
    rig = load_rig("misaligned")
    _, flipped = fig5b_build
    edges = match_image(flipped, rig).edges
    check = check_frames([flipped], rig)
    answered = 0
    for v, u in zip(*np.nonzero(edges[::23, ::7]), strict=True):      # edge pixels spread over the frame
        res = match_image(flipped, rig, seed_px=(int(u) * 7, int(v) * 23))
        if res.pairs:
            answered += 1
            assert res.rows_fit == 0 and rows_unshown(res, check), res.rows
    assert answered >= 1


def test_the_frame_as_taken_is_answered_on_its_rows(fig5b_build, capsys, tmp_path):
    rig = load_rig("misaligned")
    image, _ = fig5b_build
    res = match_image(image, rig)
    assert res.rows_fit >= 1 and rows_unshown(res, check_frames([image], rig)) == ""
    assert all(near_an_ashtray(p.median_z_mm()) for p in res.pairs), [p.median_z_mm() for p in res.pairs]
    path, out = tmp_path / "f.png", tmp_path / "m.json"
    write_png(path, image)
    code, stdout, err = run(capsys, "match", str(path), "--rig", "misaligned", "--auto", "-o", str(out))
    assert code == 0 and out.exists() and stdout.count("edge ") == len(res.pairs), (code, stdout, err)


def test_a_check_that_judges_or_a_pair_that_fits_lets_the_pairs_stand(fig5b_build):
    """The rule asks both: a check that judges, or one pair on the rows, is enough; no pair, nothing to refuse."""
    rig = load_rig("misaligned")
    _, flipped = fig5b_build
    res = match_image(flipped, rig)
    check = check_frames([flipped], rig)
    assert rows_unshown(res, dataclasses.replace(check, verdict="healthy")) == ""
    assert rows_unshown(dataclasses.replace(res, rows_fit=1), check) == ""
    assert rows_unshown(dataclasses.replace(res, pairs=[]), check) == ""
    assert rows_unshown(res, None) == ""
