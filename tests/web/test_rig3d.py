"""The rig in 3-D (issue 44, item 2, first part): psvs.optics.layout3d against the paper's construction and the
exact optics, the route that serves it and plotly.js, and the page drawing it with WebGL in Chromium, offline
(no request but to the server) and without a console error."""
import cv2
import numpy as np
import pytest

from psvs import default_rig
from psvs.io.params import load_rig
from psvs.optics.layout3d import fan_pixels, rig_layout
from psvs.optics.mirrors import mirror_planes
from psvs.web.app import create_app
from psvs.web.sources import scene_source
from tests.support.browser import shot
from tests.support.web import DISC, local_client, serving


def line_distance(p, o, d):
    """Distance (mm) of point p from the line through o along d."""
    d = d / np.linalg.norm(d)
    return float(np.linalg.norm(np.cross(p - o, d)))


@pytest.mark.parametrize("name", ["default", "misaligned", "mv1440"])
# (mv1440_misaligned's tilted glasses cut the field's corners: 6 of the 9 fan rays, tested below)
def test_the_layout_is_the_papers_construction_and_the_traced_rays(name):
    """Each view's rays, leaving the last mirror, lie on lines through its virtual camera (the paper's
    construction, III.2: O1 = (-b/2, 0, -b/2), O2 = (+b/2, 0, -b/2) on the ideal rig): the reflected right
    view's exactly, the left view's shifted sideways by the M1 plate's refraction (a plate of thickness t met at
    incidence theta: t sin(theta) (1 - cos(theta) / sqrt(n^2 - sin^2(theta))), by Snell's law) and exactly with
    no plate; every ray meets each glass inside the
    rectangle drawn for it; the rays end at the far depth; the fields at near and far lie there."""
    rig = load_rig(name)
    t, n = rig.mirrors.plate_thickness_mm, rig.mirrors.refractive_index
    layout = rig_layout(rig, 500.0, 1100.0)
    flat = rig_layout(rig.replace(plate_thickness_mm=0.0), 500.0, 1100.0)
    for line in flat["rays"]["left"]:
        assert line_distance(flat["virtual"]["left"], line[-2], line[-1] - line[-2]) < 1e-6
    b = rig.mirrors.baseline_mm
    if name != "misaligned":
        assert np.allclose(layout["virtual"]["left"], [-b / 2, 0, -b / 2], atol=1e-9)
        assert np.allclose(layout["virtual"]["right"], [b / 2, 0, -b / 2], atol=1e-9)
    planes = mirror_planes(rig)
    glasses = {g["name"].lower(): g for g in layout["glasses"]}
    assert list(glasses) == ["m1", "m2", "m3", "m4"]
    for view, mirrors in (("left", ("m1", "m2", "m3")), ("right", ("m1", "m4"))):
        lines = layout["rays"][view]
        assert len(lines) == len(fan_pixels(rig)) == 9
        for line in lines:
            assert np.allclose(line[0], 0) and line[-1][2] == pytest.approx(1100.0)
            o, end = line[-2], line[-1]
            off = line_distance(layout["virtual"][view], o, end - o)
            if view == "right":
                assert off < 1e-6
            else:
                sin = np.sqrt(1 - (line[1] @ planes["m1"].normal / np.linalg.norm(line[1])) ** 2)
                shift = t * sin * (1 - np.sqrt(1 - sin ** 2) / np.sqrt(n ** 2 - sin ** 2))
                assert off == pytest.approx(shift, abs=1e-6)
            hits = [line[1]] + list(line[3 if view == "left" else 2:-1])     # M1's front face, then mirrors
            for m, hit in zip(mirrors, hits, strict=True):   # inside the rectangle drawn for the glass
                c = glasses[m]["corners_mm"]
                s_axis, t_axis = c[1] - c[0], c[3] - c[0]
                rel = hit - c[0]
                assert abs(rel @ planes[m].normal) < 1e-6
                s, h = rel @ s_axis / (s_axis @ s_axis), rel @ t_axis / (t_axis @ t_axis)
                assert -1e-6 <= s <= 1 + 1e-6 and -1e-6 <= h <= 1 + 1e-6, (view, m, s, h)
        for depth, z in (("near", 500.0), ("far", 1100.0)):
            f = layout["field"][view][depth]
            assert f.shape == (4, 3) and np.allclose(f[:, 2], z)
    # the ideal rig: the right view's central ray leaves M4 along the axis, at X = b/2
    if name == "default":
        centre = layout["rays"]["right"][4]
        assert np.allclose(centre[-1], [b / 2, 0, 1100.0], atol=1e-6)


def test_the_sized_glasses_are_the_rig_files_and_the_plate_has_two_faces():
    layout = rig_layout(load_rig("mv1440"))
    m1 = layout["glasses"][0]
    assert all(g["sized"] == "rig file" for g in layout["glasses"])
    t = load_rig("mv1440").mirrors.plate_thickness_mm
    if t > 0:
        assert np.allclose(np.linalg.norm(m1["corners_mm"] - m1["back_mm"], axis=1), t)
    assert rig_layout(default_rig())["glasses"][0]["sized"] == "field footprint"
    cut = rig_layout(load_rig("mv1440_misaligned"))       # only the rays the build really passes
    assert len(cut["rays"]["left"]) == len(cut["rays"]["right"]) == 6
    with pytest.raises(ValueError, match="0 < near < far"):
        rig_layout(default_rig(), 800.0, 400.0)


def test_a_builds_glasses_beside_its_designs():
    """A build (mv1440_misaligned: every mirror tilted 0.1-0.17 deg, the box turned) is drawn with its glasses
    where the build has them and, dotted, where its design (the shipped mv1440 file) has them: the designed ones
    are the design file's, each built one the same rectangle moved (congruent, 0.3-0.8 mm off at a corner)."""
    build, design = rig_layout(load_rig("mv1440_misaligned")), rig_layout(load_rig("mv1440"))
    assert design["designed"] is None and rig_layout(default_rig())["designed"] is None
    for built, planned, nominal in zip(build["glasses"], build["designed"], design["glasses"], strict=True):
        assert built["name"] == planned["name"] == nominal["name"]
        np.testing.assert_allclose(planned["corners_mm"], nominal["corners_mm"], atol=1e-9)
        edges = lambda c: np.linalg.norm(np.roll(c, -1, axis=0) - c, axis=1)  # noqa: E731
        np.testing.assert_allclose(edges(built["corners_mm"]), edges(nominal["corners_mm"]), atol=1e-9)
        off = np.abs(built["corners_mm"] - nominal["corners_mm"]).max()
        assert 0.1 < off < 2.0, (built["name"], off)


@pytest.fixture(scope="module")
def app():
    return create_app(scene_source("disc", __import__("psvs.live.simulated", fromlist=["disc_scene"]).disc_scene(
        **DISC), default_rig()), default_rig())


def test_the_routes_serve_the_layout_and_plotly(app):
    with local_client(app) as c:
        r = c.get("/api/rig3d", params={"near_mm": 500, "far_mm": 900})
        assert r.status_code == 200
        data = r.json()
        assert [g["name"] for g in data["glasses"]] == ["M1", "M2", "M3", "M4"]
        assert data["range_mm"] == [500.0, 900.0] and np.allclose(data["virtual"]["right"], [50.0, 0.0, -50.0])
        assert c.get("/api/rig3d", params={"near_mm": 900, "far_mm": 500}).json() == \
            {"detail": "near_mm must be < far_mm, got 900 and 500"}
        js = c.get("/vendor/plotly.min.js")
        assert js.status_code == 200 and js.headers["content-type"].startswith("text/javascript")
        assert b"plotly.js" in js.content[:400] and len(js.content) > 1_000_000


def test_the_page_draws_the_rig_in_3d_offline(webgl_page, app):
    """The landing page draws the rig with WebGL (the canvas's pixels are not uniform), asks nothing of any
    host but the server, and logs no console error."""
    page = webgl_page
    with serving(app) as url:
        host = url.split("//")[1]
        hosts, errors = [], []
        page.on("request", lambda r: hosts.append(r.url.split("/")[2]))
        page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto(url + "/")
        page.wait_for_selector("#rig3d[data-ready='1']", timeout=60000)
        page.wait_for_selector("#rig3d canvas", timeout=10000)
        page.wait_for_timeout(500)
        png = page.locator("#rig3d").screenshot()
        img = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_GRAYSCALE)
        assert img.std() > 5 and (img < 128).mean() > 0.002, img.std()
        assert "footprint" in page.inner_text("#rig3d-note")
        shot(page, "web_rig3d.png")
        # another working range: the fields drawn where the layout of that range puts them
        page.fill("#rig3d-near", "500")
        page.fill("#rig3d-far", "900")
        page.dispatch_event("#rig3d-far", "change")
        page.wait_for_selector("#rig3d[data-range='500-900']", timeout=30000)
        names = page.evaluate("document.getElementById('rig3d').data.map(t => t.name)")
        assert any(n == "left view's field at 500 and 900 mm" for n in names), names
        assert set(hosts) == {host}, hosts
        assert errors == [], errors


@pytest.fixture(scope="module")
def textured_app():
    """The page on psvs's photo-textured scene through the default rig, with its true depth map."""
    from psvs.simulate.builtin import textured
    from psvs.simulate.render import render
    from psvs.web.sources import image_source
    r = render(textured(), default_rig(), supersample=1, truth=True)
    return create_app(image_source("textured", r.image), default_rig()), r


def test_the_dense_cloud_is_the_trusted_pixels_at_their_depth(textured_app):
    """/api/dense's cloud: points of pixels the echo supports, their Z within 2 % of the scene's true depth at
    their pixels for 90 % of them (the bad-pixel measure of docs/dense.md), the medians theirs; a blank image:
    nothing trusted, no median, an empty cloud (not a noisy answer)."""
    from psvs.web.sources import image_source
    app, r = textured_app
    with local_client(app) as c:
        res = c.post("/api/dense", json={"fast": True}).json()
    cloud = res["cloud"]
    pts = np.array(cloud["points_mm"])
    assert res["trusted_pct"] > 30 and cloud["of_points"] >= len(pts) > 5000 and len(cloud["grey"]) == len(pts)
    assert np.median(pts[:, 2]) == pytest.approx(res["median_z_mm"], rel=0.02)
    from psvs.optics.project import project_points
    uv, ok = project_points(pts, default_rig(), "left")
    ui, vi = np.rint(uv[ok]).astype(int).T
    inside = (ui >= 0) & (ui < 640) & (vi >= 0) & (vi < 480)
    assert ok.mean() > 0.99 and inside.mean() > 0.99
    truth = r.truth.depth_left_mm[vi[inside], ui[inside]]
    good = np.abs(pts[ok][inside][:, 2] / truth - 1) <= 0.02
    assert np.mean(good) >= 0.9, np.mean(good)
    maps = res["maps"]              # the full-resolution maps: the trusted pixels' depth, at their truth
    assert maps["shape"] == [480, 640] and maps["names"] == ["disparity", "z", "untrusted"]
    got = {}
    with local_client(app) as c:
        for name in maps["names"]:
            sent = c.get("/api/dense/map", params={"name": name, "run": maps["run"]})
            assert sent.status_code == 200 and sent.headers["X-Shape"] == "480,640"
            got[name] = np.frombuffer(sent.content, "<f4").reshape(480, 640)      # read back by value
        stale = c.get("/api/dense/map", params={"name": "z", "run": maps["run"] + 1})
        assert stale.status_code == 409
        assert c.get("/api/dense/map", params={"name": "depth", "run": 0}).status_code == 422
    z, truth = got["z"], r.truth.depth_left_mm
    seen = np.isfinite(z) & np.isfinite(truth)
    assert seen.mean() > 0.3 and np.mean(np.abs(z[seen] / truth[seen] - 1) <= 0.02) >= 0.9
    assert not (np.isfinite(z) & ~np.isfinite(got["disparity"])).any()       # a depth only where a disparity
    assert np.mean(np.isfinite(z)[np.isfinite(got["disparity"])]) > 0.99
    # the untrusted answers, drawn as such: exactly the answered pixels the trust test leaves out (the library's
    # own call on the same image, independent of the route)
    from psvs.dense import FAST
    from psvs.dense.build import dense_on_rig, rig_trust
    dense = dense_on_rig(r.image, default_rig(), 400.0, 1200.0, params=FAST)
    d, trusted = dense.result.disparity_left, rig_trust(dense).trusted_left
    untrusted = got["untrusted"]
    expect = np.isfinite(d) & ~trusted
    assert (np.isfinite(untrusted) == expect).all() and expect.mean() > 0.05
    np.testing.assert_array_equal(untrusted[expect], d[expect])
    np.testing.assert_array_equal(got["disparity"][trusted & np.isfinite(d)], d[trusted & np.isfinite(d)])
    blank = create_app(image_source("blank", np.full((480, 640), 90, np.uint8)), default_rig())
    with local_client(blank) as c:
        assert c.get("/api/dense/map", params={"name": "z", "run": 0}).status_code == 404
        res = c.post("/api/dense", json={"fast": True})
        # a constant image: refused before any work, in psvs disparity's words (it answered an all-NaN map)
        assert res.status_code == 422 and "the complex image is constant (every pixel 90)" in res.text
        assert c.get("/api/dense/map", params={"name": "z", "run": 0}).status_code == 404      # no run kept
    noise = create_app(image_source("noise", np.random.default_rng(3).integers(0, 256, (480, 640)).astype(np.uint8)),
                       default_rig())
    with local_client(noise) as c:
        res = c.post("/api/dense", json={"fast": True}).json()
    # sensor noise: the map holds a disparity almost everywhere, none of it supported: nothing answered (as
    # psvs disparity refuses the image), no depth
    assert res["mapped_pct"] > 90 and res["trusted_pct"] == 0 and res["answered_pct"] == 0
    assert res["median_z_mm"] is None and res["cloud"]["points_mm"] == []
    # why, in the words psvs disparity refuses the image in
    assert res["refused"].startswith("no part of the image echoes beyond chance: its strongest echo, "), res


def test_the_page_draws_the_dense_cloud(webgl_page, textured_app):
    page = webgl_page
    errors = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    with serving(textured_app[0]) as url:
        page.goto(url + "/#dense")
        page.wait_for_selector("body[data-ready='1']", timeout=60000)
        page.click("#dense")
        page.wait_for_function("Number(document.getElementById('dense-cloud').dataset.points) > 5000",
                               timeout=120000)
        page.wait_for_timeout(500)
        img = cv2.imdecode(np.frombuffer(page.locator("#dense-cloud").screenshot(), np.uint8), cv2.IMREAD_GRAYSCALE)
        assert img.std() > 5
        assert "supported beyond chance" in page.inner_text("#dense-cloud-note")
        # with the frame its millimetres are in: frame C's axes from O, a fifth of the median depth long
        axes = page.evaluate("document.getElementById('dense-cloud').data.filter(t => t.name.startsWith('frame C'))"
                             ".map(t => [t.name, t.x[1], t.y[1], t.z[1]])")
        assert [a[0] for a in axes] == ["frame C: X", "frame C: Y", "frame C: Z"]
        length = axes[0][1]
        assert 100 < length < 250 and axes[1][1:] == [0, 0, -length] and axes[2][1:] == [0, length, 0]
        assert 550 < float(page.eval_on_selector("#dense-depth", "e => e.dataset.mm")) < 1150
        # under the pointer: a pixel on the photo panel (the textured scene's truth there, within 2 %)
        u, v = 250, 250
        truth = textured_app[1].truth.depth_left_mm[v, u]
        page.locator("#dense-map").scroll_into_view_if_needed()      # the cloud's screenshot scrolled past it
        box = page.locator("#dense-map").bounding_box()
        page.mouse.move(box["x"] + (u + 0.5) * box["width"] / 640, box["y"] + (v + 0.5) * box["height"] / 480)
        z = page.eval_on_selector("#dense-pointer", "e => e.dataset.mm")
        assert z and abs(float(z) / truth - 1) <= 0.02, (z, truth, page.inner_text("#dense-pointer"))
        # the depth map at full resolution (every pixel of 640 x 480), zoomable, with a colour bar in mm
        depth = page.evaluate("(() => { const el = document.getElementById('dense-depth-map'); const t = el.data[0];"
                              " return [t.z.length, t.z[0].length, t.z[v][u], t.colorbar.title.text,"
                              " el.layout.dragmode]; })()".replace("[v][u]", f"[{v}][{u}]"))
        assert depth[:2] == [480, 640] and depth[3:] == ["Z (mm)", "zoom"]
        assert abs(depth[2] / truth - 1) <= 0.02
        # the disparity map at full resolution, zoomable, a colour bar in px, the unsupported answers in grey
        disp = page.evaluate("(() => { const el = document.getElementById('dense-disparity-map');"
                             " return [el.data[1].z.length, el.data[1].z[0].length, el.data[1].colorbar.title.text,"
                             " el.data[0].showscale, Number(el.dataset.untrusted), el.layout.dragmode]; })()")
        sent = page.evaluate("fetch('/api/dense', {method: 'POST', headers: {'Content-Type': 'application/json'},"
                             " body: JSON.stringify({fast: true})}).then(r => r.json()).then(d => fetch("
                             "`/api/dense/map?name=untrusted&run=${d.maps.run}`))"
                             ".then(r => r.arrayBuffer())"
                             ".then(b => new Float32Array(b).filter(x => !Number.isNaN(x)).length)")
        assert disp == [480, 640, "d (px)", False, sent, "zoom"] and sent > 1000, (disp, sent)
        page.locator("#dense-depth-map").scroll_into_view_if_needed()
        shot(page, "web_dense_cloud.png")
        # the cloud in the image's grey levels: each point its pixel's grey, as /api/dense sent them
        page.select_option("#dense-cloud-colour", "grey")
        page.wait_for_function("document.getElementById('dense-cloud').dataset.colour === 'grey'", timeout=10000)
        greys = page.evaluate("document.getElementById('dense-cloud').data[0].marker.color.slice(0, 5)")
        sent = page.evaluate("fetch('/api/dense', {method: 'POST', headers: {'Content-Type': 'application/json'},"
                             " body: JSON.stringify({fast: true})}).then(r => r.json())"
                             ".then(d => d.cloud.grey.slice(0, 5))")
        drawn = [[float(x) for x in c[4:-1].split(",")] for c in greys]
        assert drawn == [[g, g, g] for g in sent] and len(sent) == 5
        # another rig chosen: the old rig's dense figures and cloud are not left beside it
        page.goto(url + "/#design")
        page.select_option("#rig-choice", "clear")
        page.wait_for_function("document.body.dataset.rigChosen === 'clear'", timeout=60000)
        assert page.inner_text("#dense-depth") == "–" and page.get_attribute("#dense-depth", "data-mm") is None
        assert page.evaluate("document.getElementById('dense-cloud').hidden") is True
    assert errors == [], errors


def test_the_fast_dense_answer_on_fig5b_is_the_trusted_pixels():
    """psvs serve's default scene (fig5b: two discs, 690-720 mm, disparities 148-155 px): the fast map answers
    every pixel, most of them noise on the black backdrop; the medians shown are the trusted pixels', inside the
    truth (they were 133.5 px and 766.1 mm over every answered pixel)."""
    from psvs.simulate.builtin import fig5b
    app = create_app(scene_source("fig5b", fig5b(), default_rig()), default_rig())
    with local_client(app) as c:
        res = c.post("/api/dense", json={"fast": True}).json()
    assert res["mapped_pct"] > 90 and 2 < res["trusted_pct"] < 30 and res["answered_pct"] == res["mapped_pct"]
    assert 148 <= res["median_disparity_px"] <= 155 and 690 <= res["median_z_mm"] <= 720


def test_a_rig_the_layout_cannot_draw_is_one_line_and_the_page_goes_on(webgl_page):
    """A 3 mm lens sees past M1 (omega_1 under the half field): /api/rig3d answers 400 in one line, and the page
    says so under the 3-D view and still opens (its other panels work)."""
    rig = default_rig().replace(focal_length_mm=3.0)
    from psvs.live.simulated import disc_scene
    app = create_app(scene_source("disc", disc_scene(**DISC), rig), rig)
    with local_client(app) as c:
        r = c.get("/api/rig3d")
    assert r.status_code == 400 and r.json()["detail"].startswith("part of the camera's field never reaches M1")
    with serving(app) as url:
        webgl_page.goto(url + "/")
        webgl_page.wait_for_selector("body[data-ready='1']", timeout=60000)
        assert webgl_page.inner_text("#rig3d-note").startswith("no 3-D view of this rig: part of the camera's field")
