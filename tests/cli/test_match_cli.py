import json

import numpy as np
import pytest

from psvs import default_rig
from psvs.io.images import write_png
from psvs.simulate.builtin import builtin_scene
from psvs.simulate.render import render
from tests.cli.test_cli import EXAMPLE, run


@pytest.fixture(scope="module")
def fig5a_png(tmp_path_factory):
    path = tmp_path_factory.mktemp("img") / "fig5a.png"
    write_png(path, render(builtin_scene("fig5a"), default_rig(), seed=1).image)
    return path


def test_auto_writes_json_csv_ply_figures(capsys, tmp_path, fig5a_png):
    out, csv, ply = tmp_path / "m.json", tmp_path / "m.csv", tmp_path / "m.ply"
    figs = tmp_path / "figs"
    figs.mkdir()
    code, text, err = run(capsys, "match", str(fig5a_png), "--rig", EXAMPLE, "--auto", "-o", str(out),
                          "--csv", str(csv), "--ply", str(ply), "--figures", str(figs))
    assert code == 0, err
    data = json.loads(out.read_text())
    assert len(data["pairs"]) == 2 and data["unmatched"] == []
    pair = data["pairs"][0]
    n = pair["n"]
    assert np.array(pair["left_px"]).shape == (n, 2) and np.array(pair["right_px"]).shape == (n, 2)
    assert len(pair["disparity_px"]) == n and np.array(pair["points_mm"], dtype=float).shape == (n, 3)
    assert 580 < pair["median_z_mm"] < 720 and "median Z" in text
    assert csv.read_text().startswith("pair,u_l,v_l,u_r,v_r,disparity_px,X_mm,Y_mm,Z_mm\n")
    assert "element vertex" in ply.read_text()
    assert sorted(p.name for p in figs.iterdir()) == ["fig7_views.png", "fig8_disparity.png"]


def test_seeded(capsys, tmp_path, fig5a_png):
    from psvs.imaging.pipeline import PAPER
    from psvs.io.images import read_grey
    edges = PAPER.run(read_grey(fig5a_png))
    v, u = np.nonzero(edges)
    k = int(np.argmax(u))   # the rightmost edge pixel belongs to a left view (left views lie to the right)
    out = tmp_path / "s.json"
    code, text, _ = run(capsys, "match", str(fig5a_png), "--rig", EXAMPLE, "--seed", f"{u[k]},{v[k]}", "-o", str(out))
    assert code == 0 and len(json.loads(out.read_text())["pairs"]) == 1


@pytest.mark.parametrize("args, message", [
    (["--seed", "5,5"], r"seed (5, 5) is not on an edge pixel"),
    (["--seed", "900,5"], "is outside the 640x480 image"),
    (["--seed", "x"], "--seed must be 'u,v'"),
    (["--auto", "--pipeline", "nope.toml"], "pipeline file not found"),
])
def test_bad_seeds_and_files(capsys, tmp_path, fig5a_png, args, message):
    out = tmp_path / "m.json"
    out.write_text("earlier")
    code, _, err = run(capsys, "match", str(fig5a_png), "--rig", EXAMPLE, *args, "-o", str(out))
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1
    assert out.read_text() == "earlier"


def test_bad_images(capsys, tmp_path):
    blank, small = tmp_path / "blank.png", tmp_path / "small.png"
    write_png(blank, np.full((480, 640), 30, np.uint8))
    write_png(small, np.zeros((100, 100), np.uint8))
    for img, message in ((blank, "image is blank"), (small, "image is 100x100 px but the rig's camera is 640x480"),
                         (tmp_path / "none.png", "image not found")):
        code, _, err = run(capsys, "match", str(img), "--rig", EXAMPLE, "--auto", "-o", str(tmp_path / "o.json"))
        assert code == 2 and message in err
    code, _, err = run(capsys, "match", str(blank), "--rig", EXAMPLE, "-o", str(tmp_path / "o.json"))
    assert code == 2 and "one of the arguments --seed --auto is required" in err
