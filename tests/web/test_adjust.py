"""The Alignment panel: POST /api/adjust against the library's guide on the same inputs (the turns, the
offsets, the maps' points and values), its refusals (4xx, one line), and in headless Chromium the panel:
upload the misaligned build, run, read the turns and the "after" offset from the page."""
from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from psvs.io.params import load_rig
from psvs.mount.files import mount_toml, read_mount_text
from psvs.mount.guide import alignment_guide, working_points
from psvs.mount.layout import MountParams, mount_layout
from psvs.mount.report import guide_to_dict
from psvs.mount.seats import seats_for
from psvs.optics.design import design_mirrors
from psvs.rigs import shipped_rig_path
from psvs.web.app import MAX_BODY_BYTES, create_app
from psvs.web.sources import image_source
from tests.support.browser import shot
from tests.support.web import local_client, serving

#: (the calibrated build's stand-in, its design): the shipped builds and their designs.
CASES = [("misaligned", "clear"), ("mv1440_misaligned", "mv1440")]


def app_for(design: str):
    """The app serving ``design`` (a blank still of its camera's size: the guide needs no image)."""
    rig = load_rig(shipped_rig_path(design))
    w, h = rig.camera.image_size_px
    return create_app(image_source("blank", np.zeros((h, w), np.uint8)), rig, design)


def text_of(name: str) -> str:
    return shipped_rig_path(name).read_text(encoding="utf-8")


def turns_of_instruction(text: str) -> float:
    """'1 3/16 turns counter-clockwise' -> -1.1875; 'leave' -> 0 (an independent reader of the table)."""
    if text == "leave":
        return 0.0
    words = text.split()
    sign = {"clockwise": 1, "counter-clockwise": -1}[words[-1]]
    return sign * float(sum(Fraction(w) for w in words if w[0].isdigit()))


@pytest.fixture(scope="module", params=CASES, ids=[b for b, _ in CASES])
def answered(request):
    """The answer for the shipped build, the design the app serves, and the library's guide on them."""
    build, design = request.param
    with local_client(app_for(design)) as client:
        r = client.post("/api/adjust", json={"calibrated": text_of(build)})
    assert r.status_code == 200, r.text
    built, nominal = load_rig(shipped_rig_path(build)), load_rig(shipped_rig_path(design))
    return r.json(), built, alignment_guide(built, seats_for(nominal))


def test_the_answer_is_the_librarys_guide(answered):
    """The turns, offsets and null space are alignment_guide's on the same inputs; the table's turn text reads
    back as each screw's turns (1/16 multiples); the text lines are psvs adjust's."""
    res, _, g = answered
    assert res["guide"] == guide_to_dict(g)
    got = [turns_of_instruction(row["turn"]) for row in res["table"]]
    assert got == [t.turns for t in g.turns]
    assert all((16 * t).is_integer() for t in got) and any(got)
    assert [(row["mirror"], row["screw"]) for row in res["table"]] == [(t.mirror.upper(), t.screw) for t in g.turns]
    assert [row["deg_per_turn"] for row in res["table"]] == pytest.approx([np.degrees(t.rad_per_turn) for t in g.turns],
                                                                          abs=1e-12)
    assert res["text"][1] == f"twins' row offset before: largest {g.before_px[0]:.2f} px, RMS {g.before_px[1]:.2f} px"
    note = res["null_space_text"]
    assert len(note) == len(g.null_space) + 1 and "cannot tell them apart" in note[0]


def test_the_maps_points_and_offsets(answered):
    """The maps hold working_points (per depth, near to far) at the left view's 11 x 9 pixel grid (5 %-95 % of
    the image, read back by the optics); the weighed points' largest |offset| is the guide's before and after,
    and the turns bring every offset the guide weighs under 1 px (from over 10 px). After the turns a few
    points may leave a view (None: 10 of 234 on mv1440, at the field's edge); the guide's 'after' is over
    the rest."""
    res, built, g = answered
    pts = working_points(built, g.near_mm, g.far_mm)
    maps = res["maps"]
    w, h = built.camera.image_size_px
    assert maps["image_size_px"] == [w, h]
    assert [m["z_mm"] for m in maps["before"]] == pytest.approx([400.0, 800.0, 1200.0], abs=1e-9)
    n = [len(m["u_px"]) for m in maps["before"]]
    assert sum(n) == len(pts) and [len(m["offset_px"]) for m in maps["after"]] == n
    z = np.concatenate([[m["z_mm"]] * len(m["u_px"]) for m in maps["before"]])
    assert z == pytest.approx(pts[:, 2], abs=1e-6)
    uv = np.array([(u, v) for m in maps["before"] for u, v in zip(m["u_px"], m["v_px"], strict=True)])
    grid_u, grid_v = np.linspace(0.05 * w, 0.95 * w, 11), np.linspace(0.05 * h, 0.95 * h, 9)
    assert np.abs(uv[:, 0, None] - grid_u).min(axis=1).max() < 1e-6      # each point on a grid column, px
    assert np.abs(uv[:, 1, None] - grid_v).min(axis=1).max() < 1e-6      # and on a grid row
    for when, (largest, rms) in (("before", g.before_px), ("after", g.after_px)):
        r = np.array([np.nan if x is None else x for m in maps[when]
                      for x, k in zip(m["offset_px"], m["weighed"], strict=True)
                      if k])
        assert len(r) == g.n_points and np.isfinite(r).sum() >= (g.n_points if when == "before" else 0.9 * g.n_points)
        r = r[np.isfinite(r)]
        assert np.max(np.abs(r)) == pytest.approx(largest, abs=1e-9)
        assert np.sqrt(np.mean(r ** 2)) == pytest.approx(rms, abs=1e-9)
    assert g.before_px[0] > 10 and g.after_px[0] <= 1.0


def test_design_by_name_by_text_and_the_mounts_seats():
    """The design may be a shipped name or a rig file's text (the same guide as serving it); a mount.toml's
    seats (here with 0.35 mm screws) are used as psvs adjust --mount uses them; a pitch against them is refused."""
    built, clear = load_rig(shipped_rig_path("misaligned")), load_rig(shipped_rig_path("clear"))
    want = guide_to_dict(alignment_guide(built, seats_for(clear)))
    mount = mount_toml(mount_layout(design_mirrors(clear, search=False), MountParams(pitch_mm=0.35)), {})
    with local_client(app_for("default")) as client:
        for design in ("clear", text_of("clear")):
            r = client.post("/api/adjust", json={"calibrated": text_of("misaligned"), "design": design})
            assert r.status_code == 200 and r.json()["guide"] == want
        r = client.post("/api/adjust", json={"calibrated": text_of("misaligned"), "design": "clear", "mount": mount})
        assert r.status_code == 200, r.text
        got = r.json()["guide"]
        assert got == guide_to_dict(alignment_guide(built, read_mount_text(mount)[1])) and got["pitch_mm"] == 0.35
        r = client.post("/api/adjust", json={"calibrated": text_of("misaligned"), "mount": mount, "pitch_mm": 0.5})
        assert r.status_code == 400 and "contradicts mount.toml" in r.json()["detail"]
        designs = client.get("/api/adjust/designs").json()
        assert designs["served"] == "default" and "mv1440" in designs["shipped"] and designs["pitch_mm"] == 0.5


@pytest.mark.parametrize("body, status, says", [
    ({"calibrated": "[camera\nfocal_length_mm = 8"}, 400, "calibrated rig file: malformed TOML"),
    ({"calibrated": "[camera]\nfocal_length_mm = 8\n"}, 400, "calibrated rig file: missing table [mirrors]"),
    ({"calibrated": "@mv1440_misaligned"}, 400, "not one design"),
    ({"calibrated": "@misaligned", "design": "clearer"}, 400, "unknown rig name 'clearer'"),
    ({"calibrated": "@misaligned", "design": "/etc/passwd"}, 400, "unknown rig name"),
    ({"calibrated": "@misaligned", "design": "[camera]\nfocal_length_mm = 8\n"}, 400, "design rig file: missing"),
    ({"calibrated": "@misaligned", "mount": "[mount]\nparams = 3\n"}, 400, "mount.toml: not a mount file"),
    ({"calibrated": "@misaligned", "mount": "[seats"}, 400, "mount.toml: malformed TOML"),
    ({"calibrated": "@misaligned", "near_mm": 900, "far_mm": 500}, 400, "near_mm must be < far_mm"),
    ({"calibrated": "@misaligned", "pitch_mm": -1}, 422, "pitch_mm"),
    ({"calibrated": "@misaligned", "pitch_mm": 0.001}, 422, "pitch_mm"),
    ({"calibrated": "@misaligned", "pitch_mm": 2.0}, 422, "cannot measure: the screws cannot bring the twins"),
    ({"calibrated": "@misaligned", "rig": "clear"}, 422, "rig"),
    ({"calibrated": ""}, 422, "calibrated"),
    ({}, 422, "calibrated"),
])
def test_bad_input_is_4xx_in_one_line(body, status, says):
    """Bad files, names, designs and values: 400 or 422 with a one-line detail naming what is wrong ("@name":
    that shipped rig's text)."""
    body = {k: text_of(v[1:]) if isinstance(v, str) and v.startswith("@") else v for k, v in body.items()}
    with local_client(app_for("clear")) as client:
        r = client.post("/api/adjust", json=body)
    detail = r.json()["detail"]
    assert r.status_code == status and says in detail and "\n" not in detail, (r.status_code, detail)


def test_a_body_over_the_limit_is_413():
    with local_client(app_for("clear")) as client:
        r = client.post("/api/adjust", json={"calibrated": "#" * (MAX_BODY_BYTES + 10)})
    assert r.status_code == 413


def test_the_alignment_panel(page, tmp_path):
    """In Chromium: upload misaligned.toml, keep the served design (clear), Run; the table's turn cells and the
    shown 'after' largest offset are the library's guide; the two heat maps share one scale whose ends are the
    largest |offset| shown, and the cell of the largest 'before' offset is drawn in a saturated colour."""
    g = alignment_guide(load_rig(shipped_rig_path("misaligned")), seats_for(load_rig(shipped_rig_path("clear"))))
    upload = tmp_path / "misaligned.toml"
    upload.write_text(text_of("misaligned"), encoding="utf-8")
    with serving(app_for("clear")) as url:
        page.goto(url + "/#align")
        page.wait_for_selector("body[data-ready='1']", timeout=30000)
        for box in ("#adjust-rig", "#adjust-mount"):     # the file buttons whole, not cut to "Choose F"
            assert page.eval_on_selector(box, "e => e.getBoundingClientRect().width") >= 180
        page.set_input_files("#adjust-rig", str(upload))
        page.click("#adjust-run")
        page.wait_for_selector("body[data-adjust-done='1']", timeout=60000)
        cells = page.locator("#adjust-turns tbody td.turn")
        assert cells.count() == 8
        shown = [cells.nth(k).inner_text() for k in range(8)]
        assert [turns_of_instruction(s) for s in shown] == [t.turns for t in g.turns]
        after = page.inner_text("#adjust-after-max")
        assert after == f"{g.after_px[0]:.2f} px"
        assert float(page.get_attribute("#adjust-after-max", "data-px")) == pytest.approx(g.after_px[0], abs=1e-9)
        assert page.inner_text("#adjust-before-max") == f"{g.before_px[0]:.2f} px"
        assert "cannot tell them apart" in page.inner_text("#adjust-null")
        limit = float(page.get_attribute("#adjust-legend", "data-limit-px"))
        assert limit == pytest.approx(g.before_px[0], abs=1e-9)      # the weighed points hold the largest here
        rgb = page.evaluate("""() => {
            const res = adjust.res, c = document.getElementById('adjust-before');
            const s = c.width / res.maps.image_size_px[0];
            let best = null;
            res.maps.before.forEach((d) => d.offset_px.forEach((x, i) => {
                if (x !== null && (best === null || Math.abs(x) > Math.abs(best[0]))) best = [x, d.u_px[i], d.v_px[i]];
            }));
            return [best[0], ...c.getContext('2d').getImageData((best[1] + 0.5) * s, (best[2] + 0.5) * s, 1, 1).data];
        }""")
        assert rgb[1:4] == ([178, 24, 43] if rgb[0] > 0 else [33, 102, 172])
        shot(page, "web_alignment.png")
