"""End to end in headless Chromium: load a simulated complex image, double-click an edge on the canvas, read the
depth the page shows. Truth: the disc's depth (every rim point is at z); the click lands on the rim's projection."""


from psvs import default_rig
from psvs.web.app import create_app
from psvs.web.sources import video_source
from tests.support.browser import dblclick_px, shot
from tests.support.scenes import rim_seed
from tests.support.web import DISC, rim_point_px, serving


def test_double_click_shows_depth(page, live_server, disc_source):
    _, rig = disc_source
    page.goto(live_server + "/#measure")
    page.wait_for_selector("body[data-ready='1']", timeout=30000)
    u, v = rim_point_px(rig, "left")                      # the rim's leftmost point in the left view
    dblclick_px(page, u, v)
    page.wait_for_function("document.getElementById('depth').dataset.mm", timeout=30000)
    shown = page.inner_text("#depth")
    z = float(page.get_attribute("#depth", "data-mm"))
    shot(page, "web_double_click.png")
    assert shown.endswith(" mm") and abs(float(shown.split()[0]) - z) < 0.01
    assert abs(z - DISC["z_mm"]) <= 0.01 * DISC["z_mm"]
    assert page.inner_text("#status") == "edge matched"
    assert float(page.inner_text("#disparity").split()[0]) > 0
    # the automatic button pairs the disc with its twin: one row in the table, at the same depth
    page.click("#auto")
    page.wait_for_function("document.getElementById('seed').textContent === 'automatic'", timeout=30000)
    rows = page.locator("#pairs tbody tr")
    assert rows.count() == 1
    assert abs(float(rows.nth(0).locator("td").nth(3).inner_text()) - DISC["z_mm"]) <= 0.01 * DISC["z_mm"]


def test_live_mode_in_the_page(page, disc_video):
    """Serve a simulated video, double-click the disc's rim, start live: the page shows frames, a frame rate
    and each frame's depth (1 % of that frame's truth)."""
    path, truth, rig, scene, positions = disc_video
    with serving(create_app(video_source(str(path)), rig)) as url:
        page.goto(url + "/#measure")
        page.wait_for_selector("body[data-ready='1']", timeout=30000)
        dblclick_px(page, *rim_seed(rig, scene, positions[0]))
        page.wait_for_function("document.getElementById('depth').dataset.mm", timeout=30000)
        page.click("#workflow a[data-step='live']")           # the Live step tracks the edge picked in Measure
        page.click("#live-start")
        page.wait_for_function("Number(document.getElementById('live-frame').textContent) >= 15", timeout=30000)
        page.click("#live-stop")
        # read the frame number and its depth in one go (a poll may still be landing)
        frame, z = page.evaluate("() => [Number(document.getElementById('live-frame').textContent), "
                                 "Number(document.getElementById('live-depth').dataset.mm)]")
        assert abs(z - truth[frame % len(truth)]) <= 0.01 * truth[frame % len(truth)]
        assert float(page.inner_text("#live-fps")) > 0 and page.inner_text("#live-latency").endswith(" ms")
        shot(page, "web_live.png")


def test_live_dense_in_the_page(page, wall_video):
    """Tick dense, start live without an edge: the page shows each frame's dense map and median depth (1 % of
    that frame's truth)."""
    path, truth = wall_video
    with serving(create_app(video_source(str(path)), default_rig())) as url:
        page.goto(url + "/#live")
        page.wait_for_selector("body[data-ready='1']", timeout=30000)
        page.check("#live-dense")
        page.click("#live-start")
        page.wait_for_function("Number(document.getElementById('live-dense-z').dataset.frame) >= 3", timeout=60000)
        page.click("#live-stop")
        frame, z = page.evaluate("() => [Number(document.getElementById('live-dense-z').dataset.frame), "
                                 "Number(document.getElementById('live-dense-z').dataset.mm)]")
        assert abs(z - truth[frame % len(truth)]) <= 0.01 * truth[frame % len(truth)]
        assert page.is_visible("#live-dense-map") and page.inner_text("#live-dense-ms").endswith(" ms")
        page.wait_for_function("document.getElementById('live-dense-map').naturalWidth === 640", timeout=10000)
        shot(page, "web_live_dense.png")


def test_the_page_uploads_without_a_token(page, disc_source, tmp_path):
    """The page's own requests need nothing (psvs.web.guard): opened as the server's address, it uploads a PNG
    (a POST with its Origin, image/png) and shows it; opened with the printed ?token=, it lands on / with the
    token as a cookie and matches. Another page of this machine (another port) cannot upload."""
    import cv2
    import numpy as np
    source, rig = disc_source
    app = create_app(source, rig)
    img = np.full((480, 640), 40, np.uint8)
    cv2.rectangle(img, (100, 200), (160, 260), 220, -1)
    cv2.imwrite(str(tmp_path / "mine.png"), img)
    with serving(app) as url:
        page.goto(url + f"/?token={app.state.access.token}#measure")
        assert page.url == url + "/#measure"          # the token left the address, the step stayed
        assert page.context.cookies()[0]["sameSite"] == "Strict"
        page.wait_for_selector("body[data-ready='1']", timeout=30000)
        page.set_input_files("#upload", str(tmp_path / "mine.png"))
        page.wait_for_function("document.getElementById('source').textContent === 'image: mine.png'", timeout=30000)
        assert page.inner_text("#status") == ""
        assert app.state.session.still().name == "uploaded image"
        assert np.array_equal(app.state.session.still().grey, img)
        # a page of another origin on this machine posts another PNG as text/plain (no preflight, the CSRF the
        # issue found): refused, the image kept
        other_png = list(cv2.imencode(".png", 255 - img)[1].tobytes())
        with serving(create_app(source, rig)) as other:
            page.goto(other + "/")
            kind = page.evaluate("""async ([target, bytes]) => {
                const r = await fetch(target + "/api/upload", {method: "POST", mode: "no-cors",
                                      headers: {"Content-Type": "text/plain"}, body: new Uint8Array(bytes)});
                return r.type; }""", [url, other_png])
        assert kind == "opaque" and np.array_equal(app.state.session.still().grey, img)


def test_a_folders_frames_open_in_name_order_and_step(page, disc_source, tmp_path):
    """Open image… with several files (a folder's frames, chosen in the page): the first by name is served,
    ▶ and ◀ step through them in numeric name order (frame_2 before frame_10), each the file's pixels."""
    import cv2
    import numpy as np
    source, rig = disc_source
    app = create_app(source, rig)
    frames = {}
    for n in (10, 2, 1):
        img = np.full((480, 640), 20 * n, np.uint8)
        cv2.putText(img, str(n), (200, 300), cv2.FONT_HERSHEY_SIMPLEX, 4, 255, 8)
        frames[f"frame_{n}.png"] = img
        cv2.imwrite(str(tmp_path / f"frame_{n}.png"), img)
    with serving(app) as url:
        page.goto(url + "/#measure")
        page.wait_for_selector("body[data-ready='1']", timeout=30000)
        page.set_input_files("#upload", [str(tmp_path / name) for name in frames])
        order = []
        for k, move in enumerate((None, "#image-next", "#image-next", "#image-next", "#image-prev")):
            if move:
                page.click(move)
            expected = ["frame_1.png", "frame_2.png", "frame_10.png", "frame_1.png", "frame_10.png"][k]
            page.wait_for_function(f"document.getElementById('source').textContent === 'image: {expected}'",
                                   timeout=30000)
            assert np.array_equal(app.state.session.still().grey, frames[expected])
            order.append(page.inner_text("#image-index").strip())
        assert order == ["1 of 3", "2 of 3", "3 of 3", "1 of 3", "3 of 3"]
