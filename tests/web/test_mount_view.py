"""The Mount step (issue 44): the holder ``psvs mount`` made, opened from its mount.stl, drawn round the rig's
glasses and field rays. Truth: the file itself read by trimesh and the volume ``psvs mount`` printed; a mount
made for another rig (its glass and light elsewhere) is refused, not drawn in the wrong place."""
import base64
import re

import cv2
import numpy as np
import pytest
import trimesh

from psvs.cli.main import main
from psvs.io.params import load_rig
from psvs.web.app import create_app
from psvs.web.sources import image_source
from tests.support.web import local_client, serving

pytestmark = pytest.mark.slow        # psvs mount: the CAD kernel builds and checks the holder (~15 s)


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """psvs mount --rig clear: (the folder, the volume it printed, cm^3)."""
    import contextlib
    import io
    out = tmp_path_factory.mktemp("mount") / "m"
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        assert main(["mount", "--rig", "clear", "-o", str(out)]) == 0
    return out, float(re.search(r"([0-9.]+) cm\^3", text.getvalue())[1])


def _app(rig_name):
    import numpy as np
    return create_app(image_source("grey", np.full((480, 640), 90, np.uint8)), load_rig(rig_name), rig_name)


def test_the_mesh_is_the_files_and_another_rigs_mount_is_refused(made):
    folder, volume = made
    data = (folder / "mount.stl").read_bytes()
    body = {"stl": base64.b64encode(data).decode(), "name": "mount.stl"}
    mesh = trimesh.load(folder / "mount.stl", force="mesh")
    with local_client(_app("clear")) as c:
        r = c.post("/api/mount/mesh", json=body)
        assert r.status_code == 200, r.json()
        d = r.json()
        assert len(d["triangles"]) == len(mesh.faces) and len(d["vertices"]) == len(mesh.vertices)
        assert d["volume_cm3"] == pytest.approx(volume, abs=0.1) and d["closed"] is True
        for bad, said in (({"stl": "%%%"}, "not base64"), ({"stl": base64.b64encode(b"solid x\n").decode()},
                                                            "holds no triangle")):
            r = c.post("/api/mount/mesh", json={**body, **bad})
            assert r.status_code == 400 and said in r.json()["detail"], r.json()
    # the same mount beside a rig of another camera: it stands in that rig's light
    with local_client(create_app(image_source("grey", __import__("numpy").full((1080, 1440), 90, "uint8")),
                                 load_rig("mv1440"), "mv1440")) as c:
        r = c.post("/api/mount/mesh", json=body)
        assert r.status_code == 400 and re.search(r"stands in the way of \d+ of the rig's 50 field rays",
                                                  r.json()["detail"]), r.json()


def test_the_mount_step_draws_the_mount(webgl_page, made):
    folder, volume = made
    with serving(_app("clear")) as url:
        webgl_page.goto(url + "/#mount")
        webgl_page.wait_for_selector("body[data-ready='1']", timeout=60000)
        webgl_page.set_input_files("#mount-stl", str(folder / "mount.stl"))
        webgl_page.wait_for_function("document.body.dataset.mountDone === '1'", timeout=60000)
        n = len(trimesh.load(folder / "mount.stl", force="mesh").faces)
        assert int(webgl_page.get_attribute("#mount3d", "data-triangles")) == n
        assert f"{n} triangles" in webgl_page.inner_text("#mount-status")
        names = webgl_page.evaluate("document.getElementById('mount3d').data.map(t => t.name)")
        assert any(x.startswith("mount.stl") for x in names) and any("field rays" in x for x in names)
        # the landing view's rig shows the mount once one was opened, its triangles the file's
        assert webgl_page.get_attribute("#rig3d", "data-mount") == "mount.stl"
        drawn = webgl_page.evaluate("document.getElementById('rig3d').data.filter(t => t.name.startsWith('mount.stl'))"
                                    ".map(t => t.i.length)")
        assert drawn == [n]
        webgl_page.wait_for_selector("#mount3d canvas", timeout=10000)
        drawn = cv2.imdecode(np.frombuffer(webgl_page.locator("#mount3d").screenshot(), np.uint8), cv2.IMREAD_GRAYSCALE)
        assert drawn.std() > 5 and (drawn < 128).mean() > 0.002, drawn.std()     # WebGL drew: not uniform
        from tests.support.browser import shot
        shot(webgl_page, "web_mount_step.png")


def test_the_page_makes_the_mount_of_its_rig_and_offers_its_files(made, monkeypatch):
    """POST /api/mount/make builds what psvs mount builds for the served rig: its mesh (the downloaded mount.stl
    read back by trimesh), the volume psvs mount printed, and every file, each read back by its own reader
    (trimesh, tomllib, OpenCV, csv) and equal to the CLI's where the file is deterministic. Before a mount, after
    the rig changed or for a name it has not: no file. A layout that cannot be built says why (422), a body out of
    bounds is refused (422), and without the CAD extra the page says which extra (409)."""
    import csv
    import io
    import tomllib
    folder, volume = made
    with local_client(_app("clear")) as c:
        assert c.get("/api/mount/file/mount.stl").status_code == 409
        r = c.post("/api/mount/make", json={})
        assert r.status_code == 200, r.json()
        d = r.json()
        assert d["volume_cm3"] == pytest.approx(volume, abs=0.1) and d["closed"] is True
        assert d["files"] == ["mount.step", "mount.stl", "drawing.svg", "drawing.png", "bom.csv", "mount.toml"]
        assert re.search(r"\d+ field rays, 0 blocked", d["checks"]), d["checks"]
        got = {name: c.get(f"/api/mount/file/{name}") for name in d["files"]}
        assert all(g.status_code == 200 for g in got.values())
        assert got["mount.stl"].headers["content-disposition"] == 'attachment; filename="mount.stl"'
        mesh = trimesh.load(io.BytesIO(got["mount.stl"].content), file_type="stl", force="mesh")
        assert len(mesh.faces) == len(d["triangles"]) and mesh.volume / 1000 == pytest.approx(volume, abs=0.1)
        assert tomllib.loads(got["mount.toml"].text) == tomllib.loads((folder / "mount.toml").read_text())
        assert list(csv.reader(io.StringIO(got["bom.csv"].text))) == list(csv.reader(
            io.StringIO((folder / "bom.csv").read_text())))
        png = cv2.imdecode(np.frombuffer(got["drawing.png"].content, np.uint8), cv2.IMREAD_UNCHANGED)
        assert png.shape == cv2.imread(str(folder / "drawing.png"), cv2.IMREAD_UNCHANGED).shape
        assert got["mount.step"].content.startswith(b"ISO-10303-21;")
        assert c.get("/api/mount/file/mount.obj").status_code == 404
        r = c.post("/api/mount/make", json={"wall_mm": 40})
        assert r.status_code == 422 and r.json()["detail"].startswith("cannot build the mount: "), r.json()
        assert c.get("/api/mount/file/mount.stl").status_code == 200        # the last good mount stays
        for bad in ({"interface": "m42"}, {"wall_mm": 0}, {"pitch": 0.5}):
            assert c.post("/api/mount/make", json=bad).status_code == 422, bad
        assert c.post("/api/rig", json={"name": "misaligned"}).status_code == 200
        assert c.get("/api/mount/file/mount.stl").status_code == 409         # made for the rig served before

        from psvs.mount.cad import MissingExtra

        def missing():
            raise MissingExtra("the mount needs the optional extra 'cad' (build123d): pip install 'psvs[cad]'")
        monkeypatch.setattr("psvs.web.api_mount.require_cad", missing)
        r = c.post("/api/mount/make", json={})
        assert r.status_code == 409 and "psvs[cad]" in r.json()["detail"]


def test_the_mount_step_makes_the_mount_in_the_page(webgl_page, made):
    """A click on "Make the mount": the mesh drawn round the glass and the light, one mount on the landing view's
    rig (a mount opened after it replaces it), and a download link for each file."""
    folder, volume = made
    with serving(_app("clear")) as url:
        webgl_page.goto(url + "/#mount")
        webgl_page.wait_for_selector("body[data-ready='1']", timeout=60000)
        webgl_page.click("#mount-make")
        webgl_page.wait_for_function("document.body.dataset.mountDone === '1'", timeout=120000)
        status = webgl_page.inner_text("#mount-status")
        assert "0 blocked" in status and f"{volume:.1f} cm³" in status, status
        hrefs = webgl_page.eval_on_selector_all("#mount-files a", "as => as.map(a => a.getAttribute('href'))")
        assert hrefs == [f"/api/mount/file/{n}" for n in ("mount.step", "mount.stl", "drawing.svg", "drawing.png",
                                                          "bom.csv", "mount.toml")]
        webgl_page.wait_for_selector("#mount3d canvas", timeout=10000)
        from tests.support.browser import shot
        shot(webgl_page, "web_mount_made.png")
        n = len(trimesh.load(folder / "mount.stl", force="mesh").faces)
        webgl_page.set_input_files("#mount-stl", str(folder / "mount.stl"))
        webgl_page.wait_for_function("document.body.dataset.mountDone === '1'", timeout=60000)
        drawn = webgl_page.evaluate("document.getElementById('rig3d').data.filter(t => t.name.startsWith('mount'))"
                                    ".map(t => t.i.length)")
        assert drawn == [n]
