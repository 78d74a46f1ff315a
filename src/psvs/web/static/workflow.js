"use strict";
// The builder's workflow (issue 44): one view per step, reachable by URL (#design ... #robot), the rig chosen
// in the page (POST /api/rig), the glass to cut, the capture's card and folder (POST /api/capture/setup) and
// the self-check of the current image (POST /api/check). Uses app.js's $, api and state.

const STEPS = ["design", "mount", "capture", "align", "check", "measure", "dense", "live", "robot"];

// Show the step the URL names (the first, Design, when it names none) and mark it in the header's links.
function showStep() {
  const asked = location.hash.replace(/^#/, "");
  const step = STEPS.includes(asked) ? asked : "design";
  for (const s of document.querySelectorAll("section.step")) s.hidden = s.dataset.step !== step;
  for (const a of document.querySelectorAll("#workflow a")) {
    if (a.dataset.step === step) a.setAttribute("aria-current", "step"); else a.removeAttribute("aria-current");
  }
  document.body.dataset.step = step;
  // plotly sizes a plot to its element: one drawn while hidden is redrawn at its size once shown
  if (typeof Plotly !== "undefined") {
    for (const id of ["rig3d", "mount3d", "dense-cloud", "dense-depth-map", "dense-disparity-map", "dense-left-zoom",
                      "dense-right-zoom", "image-zoom", "robot3d", "live-cloud"]) {
      const el = $(id);
      if (el && el.dataset.ready && el.offsetParent !== null) Plotly.Plots.resize(el);
    }
  }
}
window.addEventListener("hashchange", showStep);
showStep();

// The header's "Open image…" is a label round a hidden file input: Enter or Space opens it from the keyboard.
document.querySelector("label.upload").addEventListener("keydown", (e) => {
  if (e.key === "Enter" || e.key === " ") { e.preventDefault(); $("upload").click(); }
});

function showGlass(rig) {
  const body = $("glass").querySelector("tbody");
  body.textContent = "";
  const mm = (x) => (x === null ? "unbounded" : x.toFixed(2));
  for (const g of rig.glass) {
    const tr = document.createElement("tr");
    for (const v of [g.mirror, mm(g.along_mm), mm(g.height_mm), g.thickness_mm === null ? "–" : g.thickness_mm.toFixed(2)]) {
      const td = document.createElement("td"); td.textContent = v; tr.appendChild(td);
    }
    body.appendChild(tr);
  }
  $("glass-note").textContent = rig.glass.some((g) => g.along_mm === null) ?
    "This rig file gives no mirror sizes (the paper's ideal planes): psvs design --rig RIG sizes them for the lens." :
    `Rig: ${rig.name}. Sizes of the glass itself, mm; add the holder's seat to each side as docs/mount.md says.`;
}

// The header and every panel that depends on what the server holds: the rig (name, f, b, plate; calibrated
// or a design), the image, the capture's card and folder.
function showInfo(info) {
  state.uploadTypes = info.upload_types;       // what /api/upload takes (psvs.web.guard.UPLOAD_TYPES)
  $("source").textContent = `image: ${info.source.name} (${info.source.kind}, ${info.image_size_px.join("x")} px)`;
  const rig = info.rig, cal = rig.calibration;
  const status = cal ? `calibrated: RMS ${cal.rms_px.toFixed(3)} px from ${cal.images} images` :
    (rig.build ? "no calibration record" : "not calibrated (a design)");
  $("rig").textContent = `rig: ${rig.name} (f ${rig.focal_length_mm.toFixed(3)} mm, b ${rig.baseline_mm.toFixed(2)} mm, ` +
    `plate ${rig.plate_thickness_mm.toFixed(2)} mm) — ${status}; ` +
    (rig.build ? "a build: twins matched on rectified rows" : "the paper's geometry: twins on image rows");
  showGlass(rig);
  $("live-start").disabled = !info.source.live;
  $("capture-start").disabled = !info.source.live || !info.capture;
  if (!info.source.live) $("capture-folder").textContent = "Capture reads a camera or a video: open a video " +
    "or choose a camera above.";
  else if (info.capture) $("capture-folder").textContent = `Show the printed card (${info.capture.target}) to both ` +
    `views; each good pose is saved once into ${info.capture.folder}.`;
  else $("capture-folder").textContent = "Choose the card's target.toml and a new folder above, then start.";
}

function stepStatus(id, text, ok) { const s = $(id); s.textContent = text || ""; s.className = ok ? "ok" : "bad"; }

// What the page shows of results computed through a rig (a match, a dense map and its cloud, a check): forgotten
// when the rig changes, as the server forgets them, so that no figure of the old rig stands beside the new one.
function forgetResults() {
  state.result = null; state.denseCloud = null; state.denseMaps = null;
  for (const id of ["dense-disparity", "dense-depth", "dense-pointer", "check-verdict", "check-rms", "check-max",
                    "check-tiles"]) { $(id).textContent = "–"; delete $(id).dataset.mm; }
  for (const id of ["check-reason", "check-explained", "dense-cloud-note"]) $(id).textContent = "";
  $("mount-files").hidden = true;                 // a mount made for the old rig: the server forgot it too
  for (const id of ["dense-map", "dense-left", "dense-right", "check-map"]) $(id).removeAttribute("src");
  for (const id of ["dense-cloud", "dense-depth-map", "dense-disparity-map", "dense-left-zoom", "dense-right-zoom"]) {
    $(id).hidden = true;
  }
  $("check-verdict").className = "";
  draw();
}

async function chooseRig(body) {
  stepStatus("rig-status", "loading the rig…", true);
  try {
    const r = await api("/api/rig", body);
    forgetResults();
    showInfo(await api("/api/info"));
    await rig3dInit();
    stepStatus("rig-status", `now using ${r.name}`, true);
    document.body.dataset.rigChosen = r.name;
  } catch (e) { stepStatus("rig-status", "rig: " + e.message); document.body.dataset.rigChosen = "error"; }
}

async function workflowInit(served, shipped) {
  const sel = $("rig-choice");
  fillSelect(sel, [["", `served: ${served}`], ...shipped.map((n) => [n, n])]);
  sel.addEventListener("change", () => { if (sel.value) chooseRig({ name: sel.value }); });
  $("rig-file").addEventListener("change", async (e) => {
    const f = e.target.files[0];
    if (f) await chooseRig({ text: await f.text(), file_name: f.name });
  });
}

$("capture-setup").addEventListener("click", async () => {
  const f = $("capture-target").files[0];
  if (!f) { $("capture-hint").textContent = "choose the card's target.toml (psvs target writes one)"; return; }
  try {
    const r = await api("/api/capture/setup", { target: await f.text(), folder: $("capture-dir").value });
    showInfo(await api("/api/info"));
    $("capture-hint").textContent = `card: ${r.target}; views go to ${r.folder}`;
  } catch (e) { $("capture-hint").textContent = "capture: " + e.message; }
});

// Calibrate: POST /api/calibrate starts psvs calibrate in the server; its state is polled until it is done.
$("calibrate-run").addEventListener("click", async () => {
  document.body.dataset.calibrateDone = "";
  const folder = $("calibrate-dir").value.trim();
  try {
    const r = await api("/api/calibrate", folder ? { folder } : {});
    stepStatus("calibrate-status", `calibrating ${r.folder}… (a bundle adjustment of every view: a minute or two)`, true);
    let s;
    do {
      await new Promise((res) => setTimeout(res, 500));
      s = await api("/api/calibrate/state");
    } while (s.running);
    if (s.error) throw new Error(s.error);
    const c = s.result;
    $("calibrate-rms").textContent = `${c.rms_px.toFixed(4)} px (left ${c.rms_left_px.toFixed(4)}, right ${c.rms_right_px.toFixed(4)})`;
    $("calibrate-used").textContent = `${c.used} (${c.kinds})` +
      (Object.keys(c.skipped).length ? `; skipped ${Object.keys(c.skipped).join(", ")}` : "");
    $("calibrate-baseline").textContent = `${c.baseline_mm.toFixed(3)} ± ${c.baseline_sigma_mm.toFixed(3)} mm`;
    $("calibrate-file").textContent = c.file;
    forgetResults();
    showInfo(await api("/api/info"));
    await rig3dInit();
    stepStatus("calibrate-status", `calibrated: now using ${c.file}` + (c.held_by_prior.length ?
      `; the views did not pin ${c.held_by_prior.join(", ")} (held near the design)` : ""), true);
    document.body.dataset.calibrateDone = "1";
  } catch (e) { stepStatus("calibrate-status", "calibrate: " + e.message); document.body.dataset.calibrateDone = "error"; }
});

$("check-run").addEventListener("click", async () => {
  document.body.dataset.checkDone = "";
  stepStatus("check-status", "checking the twins' rows…", true);
  try {
    const r = await api("/api/check", { near_mm: Number($("check-near").value), far_mm: Number($("check-far").value),
                                         tolerance_px: Number($("check-tolerance").value) });
    const v = $("check-verdict");
    v.textContent = r.verdict; v.className = r.verdict === "healthy" ? "good" : "bad";
    $("check-rms").textContent = fmt(r.row_offset_rms_px, 2, "px") +
      (r.uncertainty_px === null ? "" : ` ± ${r.uncertainty_px.toFixed(2)}`);
    $("check-max").textContent = fmt(r.row_offset_max_px, 2, "px");
    $("check-tiles").textContent = `${r.tiles} of ${r.tiles_tried} tiles (${r.judged_px} px)`;
    $("check-reason").textContent = r.reason;
    $("check-explained").textContent = r.explanation ? "best explained by " + r.explanation : "";
    $("check-map").src = r.map_png ? "data:image/png;base64," + r.map_png : "";
    stepStatus("check-status", `${r.image}: ${r.verdict}`, r.verdict === "healthy");
    document.body.dataset.checkDone = r.verdict;
  } catch (e) { stepStatus("check-status", "check: " + e.message); document.body.dataset.checkDone = "error"; }
});

// A file's bytes as base64 (in slices: String.fromCharCode takes a bounded number of arguments).
function base64Of(buffer) {
  const bytes = new Uint8Array(buffer);
  let text = "";
  for (let k = 0; k < bytes.length; k += 0x8000) text += String.fromCharCode(...bytes.subarray(k, k + 0x8000));
  return btoa(text);
}

// A mount's mesh in the Mount step's 3-D view and on the landing view's rig (replacing a mount shown before).
async function showMount(mesh, name) {
  if (!rig3dState.layout) throw new Error("the rig's layout is not drawn (see the Design step)");
  await drawMount3d($("mount3d"), rig3dState.layout, mesh);
  if (typeof Plotly !== "undefined" && $("rig3d").data) {
    const before = $("rig3d").data.map((t, k) => (t.name || "").startsWith("mount") ? k : -1).filter((k) => k >= 0);
    if (before.length) await Plotly.deleteTraces($("rig3d"), before);
    await Plotly.addTraces($("rig3d"), mountTrace(mesh));
    $("rig3d").dataset.mount = name;
  }
}

function meshText(mesh) {
  return `${mesh.triangles.length} triangles, ${mesh.volume_cm3} cm³` +
    (mesh.closed ? ", one closed shell" : ", not a closed shell (a slicer must repair it)");
}

$("mount-stl").addEventListener("change", async (e) => {
  const f = e.target.files[0];
  if (!f) return;
  document.body.dataset.mountDone = "";
  stepStatus("mount-status", "reading the mesh…", true);
  try {
    const mesh = await api("/api/mount/mesh", { stl: base64Of(await f.arrayBuffer()), name: f.name });
    await showMount(mesh, f.name);
    stepStatus("mount-status", `${f.name}: ${meshText(mesh)}; the rig's field rays pass it`, true);
    document.body.dataset.mountDone = "1";
  } catch (err) { stepStatus("mount-status", "mount: " + err.message); document.body.dataset.mountDone = "error"; }
});

$("mount-make").addEventListener("click", async () => {
  document.body.dataset.mountDone = "";
  $("mount-files").hidden = true;
  stepStatus("mount-status", "building the mount and checking it against the light (a few seconds)…", true);
  $("mount-make").disabled = true;
  try {
    const mesh = await api("/api/mount/make", { interface: $("mount-interface").value,
      lens_diameter_mm: Number($("mount-lens").value), wall_mm: Number($("mount-wall").value),
      pitch_mm: Number($("mount-pitch").value) });
    await showMount(mesh, "mount.stl");
    const links = $("mount-files");
    links.replaceChildren(document.createTextNode("download: "));
    for (const name of mesh.files) {
      const a = document.createElement("a");
      a.href = "/api/mount/file/" + encodeURIComponent(name); a.download = name; a.textContent = name;
      links.append(a, " ");
    }
    links.hidden = false;
    stepStatus("mount-status", `the mount of this page's rig: ${mesh.checks}; ${meshText(mesh)}`, true);
    document.body.dataset.mountDone = "1";
  } catch (err) { stepStatus("mount-status", "mount: " + err.message); document.body.dataset.mountDone = "error"; }
  finally { $("mount-make").disabled = false; }
});

// A run's figures and its 3-D view (a run the page ran, or one psvs track wrote).
async function showRun(run) {
  const r = run.report, mm = (s) => (s.rms === null ? "–" : `${s.rms.toFixed(3)} / ${s.max.toFixed(3)} mm`);
  $("robot-welded").textContent = `${r.welded_mm.toFixed(1)} mm`;
  $("robot-lateral").textContent = mm(r.lateral_mm);
  $("robot-vertical").textContent = mm(r.vertical_mm);
  $("robot-seen").textContent = `${r.valid_frames} of ${r.cycles} cycles`;
  $("robot-stop").textContent = `stopped: ${r.stop}`;
  const h = r.health;
  $("robot-health").textContent = h === null ? "not run" : (h.verdict || "no step taken") +
    (h.row_offset_rms_px === null ? "" : `, ${h.row_offset_rms_px.toFixed(2)} ± ${h.uncertainty_px.toFixed(2)} px`) +
    ` (${h.steps} steps, ${h.cost_pct.toFixed(1)} % of the sensor's time)`;
  $("robot-health").classList.toggle("bad", h !== null && h.verdict === "drifted");
  await drawRobot3d($("robot3d"), run);
  $("robot3d-note").textContent = `${run.seam_mm.length} seam points measured` +
    (run.step > 1 ? ` (every ${run.step}th cycle drawn)` : "") + "; the PSVS at the last cycle: its light " +
    `through the glasses and both views' fields (${run.sensor.mounting} mounting, this page's rig); the ` +
    "deviations over the welded part, as report.json states them; drag to turn, scroll to zoom.";
}

$("robot-run").addEventListener("change", async (e) => {
  const files = [...e.target.files];
  const log = files.find((f) => f.name.toLowerCase().endsWith(".csv"));
  const report = files.find((f) => f.name.toLowerCase().endsWith(".json"));
  document.body.dataset.robotDone = "";
  if (!log || !report) {
    stepStatus("robot-status", "select both files psvs track wrote into the run's folder: log.csv and report.json");
    return;
  }
  stepStatus("robot-status", "reading the run…", true);
  try {
    const run = await api("/api/robot/run", { log: await log.text(), report: await report.text() });
    await showRun(run);
    stepStatus("robot-status", `${log.name} and ${report.name}: ${run.report.cycles} cycles`, true);
    document.body.dataset.robotDone = "1";
  } catch (err) { stepStatus("robot-status", "run: " + err.message); document.body.dataset.robotDone = "error"; }
});

$("robot-track").addEventListener("click", async () => {
  document.body.dataset.robotDone = "";
  $("robot-track").disabled = true;
  try {
    const start = await api("/api/robot/track", { scene: $("robot-scene").value,
      speed_mm_s: Number($("robot-speed").value), length_mm: Number($("robot-length").value) });
    stepStatus("robot-status", `tracking: the hand-eye session, then ${start.expected} control cycles…`, true);
    let st;
    do {
      await new Promise((ok) => setTimeout(ok, 500));
      st = await api("/api/robot/track");
      if (st.cycles) stepStatus("robot-status", `tracking: cycle ${st.cycles} of about ${st.expected}…`, true);
    } while (st.running);
    if (st.error) throw new Error(st.error);
    if (!st.run) throw new Error("the rig changed while it ran: run it again");
    await showRun(st.run);
    stepStatus("robot-status", `the simulated run through this page's rig: ${st.run.report.cycles} cycles`, true);
    document.body.dataset.robotDone = "1";
  } catch (err) { stepStatus("robot-status", "run: " + err.message); document.body.dataset.robotDone = "error"; }
  finally { $("robot-track").disabled = false; }
});

// A local video chosen in the Capture or Live step: sent to the server, which serves it from now on (its first
// frame the current image; live mode and the capture read its frames in a loop).
for (const input of document.querySelectorAll(".video-file")) {
  input.addEventListener("change", async (e) => {
    const file = e.target.files[0];
    if (!file) return;
    const say = (text, ok) => { stepStatus("video-status", text, ok); stepStatus("capture-hint", text, ok); };
    document.body.dataset.videoDone = "";
    say(`sending ${file.name}…`, true);
    try {
      const r = await fetch("/api/source/video?name=" + encodeURIComponent(file.name), {
        method: "POST", body: file, headers: { "Content-Type": file.type || "application/octet-stream" } });
      const d = await r.json();
      if (!r.ok) throw new Error(d.detail || r.statusText);
      showInfo(await api("/api/info"));
      state.result = null; await loadImage(); schedulePreview();
      say(`${d.name}: served in a loop at ${d.fps.toFixed(1)} frames/s`, true);
      document.body.dataset.videoDone = "1";
    } catch (err) { say("video: " + err.message); document.body.dataset.videoDone = "error"; }
  });
}

// A camera of this machine chosen in the Capture or Live step: found (POST /api/cameras, what psvs cameras lists),
// then served from now on with the settings given (its first frame the current image), as psvs serve --camera.
for (const box of document.querySelectorAll(".camera-choice")) {
  box.append(document.getElementById("camera-choice-template").content.cloneNode(true));   // one chooser's markup
  const q = (c) => box.querySelector(c);
  const say = (text, ok) => { stepStatus("video-status", text, ok); stepStatus("capture-hint", text, ok); };
  q(".camera-find").addEventListener("click", async () => {
    say("looking for cameras…", true);
    try {
      const d = await api("/api/cameras", { opencv: true });
      const list = q(".camera-list");
      list.replaceChildren(...d.cameras.map((c) => new Option(`${c.spec}: ${c.label}`, c.spec)));
      if (d.cameras.length) q(".camera-spec").value = d.cameras[0].spec;
      else list.replaceChildren(new Option("(none found)", ""));
      say(`${d.cameras.length} camera(s) found` + (d.missing.length ? "; " + d.missing.join("; ") : ""),
          d.cameras.length > 0);
    } catch (err) { say("cameras: " + err.message); }
  });
  q(".camera-list").addEventListener("change", (e) => { if (e.target.value) q(".camera-spec").value = e.target.value; });
  q(".camera-use").addEventListener("click", async () => {
    const exposure = q(".camera-exposure").value, trigger = q(".camera-trigger").value;
    const body = { camera: q(".camera-spec").value.trim(),
                   features: q(".camera-features").value.split("\n").map((l) => l.trim()).filter((l) => l) };
    if (exposure) body.exposure_us = Number(exposure);
    if (trigger) body.trigger = trigger;
    document.body.dataset.cameraDone = "";
    say(`opening camera ${body.camera}…`, true);
    try {
      const d = await api("/api/source/camera", body);
      showInfo(await api("/api/info"));
      state.result = null; await loadImage(); schedulePreview();
      say(`${d.name}: served (live mode and the capture read its frames)`, true);
      document.body.dataset.cameraDone = "1";
    } catch (err) { say("camera: " + err.message); document.body.dataset.cameraDone = "error"; }
  });
}

// The rig's view over another working range (its fields at near and far, the rays out to far).
for (const id of ["rig3d-near", "rig3d-far"]) $(id).addEventListener("change", () => rig3dInit());

// The page opens: the header, the panels, the rig in 3-D, the image (app.js draws it).
(async function init() {
  try {
    showInfo(await api("/api/info"));
    await adjustInit();
    await rig3dInit();
    await loadImage();
    await preview();
    document.body.dataset.ready = "1";
  } catch (e) { setStatus(e.message); }
})();
