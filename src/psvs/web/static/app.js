// psvs web UI: plain JS and canvas. The server does all computation (psvs.web.app); this draws.
"use strict";
const $ = (id) => document.getElementById(id);
const PALETTE = ["#e53935", "#1e88e5", "#43a047", "#fb8c00", "#8e24aa", "#00acc1", "#6d4c41", "#d81b60",
                 "#7cb342", "#3949ab"];
const state = { image: null, edges: null, result: null, seed: null, live: false, liveFrame: null, liveState: null };
const canvas = $("image"), ctx = canvas.getContext("2d");

function setStatus(text, ok) { const s = $("status"); s.textContent = text || ""; s.className = ok ? "ok" : ""; }

async function api(path, body) {
  const opts = body === undefined ? {} : { method: "POST", headers: { "Content-Type": "application/json" },
                                           body: JSON.stringify(body) };
  const r = await fetch(path, opts);
  const data = await r.json().catch(() => ({}));
  if (!r.ok) throw new Error(data.detail || `${r.status} ${r.statusText}`);
  return data;
}

function steps() {
  const out = [], f = $("filter").value, size = Number($("filter-size").value), bin = $("binarise").value;
  if (f === "median" || f === "mean") out.push({ op: f, ksize: size });
  else if (f === "gaussian") out.push({ op: f, sigma: size / 3 });
  else if (f === "bilateral") out.push({ op: f, diameter: size });
  if (bin === "fixed") out.push({ op: "threshold", level: Number($("level").value) });
  else if (bin !== "none") out.push({ op: "threshold", method: bin });
  out.push({ op: $("edges").value });
  return out;
}

function matchBody(seed) {
  return { steps: steps(), seed: seed, near_mm: Number($("near").value), far_mm: Number($("far").value) };
}

function loadImg(src) {
  return new Promise((resolve, reject) => {
    const img = new Image();
    img.onload = () => resolve(img);
    img.onerror = () => reject(new Error("could not load " + src));
    img.src = src;
  });
}

async function loadImage() {
  state.image = await loadImg("/api/image.png?t=" + Date.now());
  $("image-zoom").hidden = true;               // a zoomable view of the image before is not of this one
  canvas.width = state.image.width; canvas.height = state.image.height;
  draw();
}

function dot(c, x, y, colour) { c.fillStyle = colour; c.fillRect(x - 0.5, y - 0.5, 1.6, 1.6); }

function draw() {
  const base = state.live && state.liveFrame ? state.liveFrame : ($("show-edges").checked && state.edges) || state.image;
  if (!base) return;
  ctx.drawImage(base, 0, 0, canvas.width, canvas.height);
  if (state.live && state.liveState) {
    const s = state.liveState;
    (s.left_px || []).forEach(([u, v]) => dot(ctx, u, v, $("sel-colour").value));
    (s.right_px || []).forEach(([u, v]) => dot(ctx, u, v, $("twin-colour").value));
    return;
  }
  const res = state.result;
  if (!res) return;
  const seeded = res.seed_px !== null;
  res.pairs.forEach((p, k) => {
    const cl = seeded ? $("sel-colour").value : PALETTE[k % PALETTE.length], cr = seeded ? $("twin-colour").value : cl;
    p.left_px.forEach(([u, v]) => dot(ctx, u, v, cl));
    p.right_px.forEach(([u, v]) => dot(ctx, u, v, cr));
  });
  if (seeded) {
    ctx.strokeStyle = "#ffeb3b"; ctx.lineWidth = 1.5;
    ctx.beginPath(); ctx.arc(res.seed_px[0], res.seed_px[1], 6, 0, 2 * Math.PI); ctx.stroke();
  }
}

let previewTimer = null;
function schedulePreview() { clearTimeout(previewTimer); previewTimer = setTimeout(preview, 150); }

async function preview() {
  try {
    const data = await api("/api/preview", { steps: steps() });
    const st = data.stages, last = st[st.length - 1];
    const binary = st.filter((s) => s.binary && s !== last).pop() || st[st.length - 2] || last;
    $("binary").src = binary.png; $("edgemap").src = last.png;
    state.edges = await loadImg(last.png);
    setStatus("");
    draw();
  } catch (e) { setStatus("pipeline: " + e.message); }
}

function fmt(x, digits, unit) { return x === null || x === undefined || !isFinite(x) ? "–" : `${x.toFixed(digits)} ${unit}`; }

function showResult(res) {
  state.result = res;
  const tbody = $("pairs").querySelector("tbody");
  tbody.innerHTML = "";
  res.pairs.forEach((p, k) => {
    const tr = document.createElement("tr");
    tr.innerHTML = `<td style="color:${PALETTE[k % PALETTE.length]}">${k}</td><td>${p.n}</td>` +
      `<td>${p.median_disparity_px.toFixed(2)}</td><td>${p.median_z_mm === null ? "–" : p.median_z_mm.toFixed(2)}</td>`;
    tbody.appendChild(tr);
  });
  const first = res.pairs[0];
  $("seed").textContent = res.seed_px ? `(${res.seed_px[0]}, ${res.seed_px[1]})` : "automatic";
  $("disparity").textContent = first ? fmt(first.median_disparity_px, 2, "px") : "–";
  $("depth").textContent = first ? fmt(first.median_z_mm, 2, "mm") : "–";
  $("depth").dataset.mm = first && first.median_z_mm !== null ? String(first.median_z_mm) : "";
  $("npairs").textContent = res.pairs.reduce((a, p) => a + p.n, 0);
  if (!res.pairs.length) {
    setStatus(res.seed_px ? `no twin for this edge (double-click an edge of the left view): ${res.chance.text}`
      : `no pair: ${res.chance.text}`);
  }
  else setStatus((res.seed_px ? "edge matched" : `${res.pairs.length} edge pairs, ${res.unmatched.length} without a twin`)
    + (res.model_note ? ` (${res.model_note})` : ""), true);
  plotFig8(res);
  draw();
}

function axes(c, x0, x1, y0, y1, xlabel, ylabel) {
  const W = c.canvas.width, H = c.canvas.height, m = { l: 50, r: 10, t: 10, b: 32 };
  c.clearRect(0, 0, W, H);
  c.strokeStyle = "#444"; c.fillStyle = "#444"; c.font = "11px sans-serif"; c.lineWidth = 1;
  c.strokeRect(m.l, m.t, W - m.l - m.r, H - m.t - m.b);
  if (x1 <= x0) x1 = x0 + 1;
  if (y1 <= y0) { y0 -= 0.5; y1 += 0.5; }
  const sx = (x) => m.l + (x - x0) / (x1 - x0) * (W - m.l - m.r);
  const sy = (y) => H - m.b - (y - y0) / (y1 - y0) * (H - m.t - m.b);
  for (let i = 0; i <= 4; i++) {
    const xv = x0 + (x1 - x0) * i / 4, yv = y0 + (y1 - y0) * i / 4;
    c.fillText(xv.toFixed(xv > 100 ? 0 : 1), sx(xv) - 10, H - m.b + 13);
    c.fillText(yv.toFixed(Math.abs(y1 - y0) > 20 ? 0 : 2), 2, sy(yv) + 4);
  }
  c.fillText(xlabel, W / 2 - 20, H - 4);
  c.fillText(ylabel, m.l + 4, m.t + 12);
  return [sx, sy];
}

function plotFig8(res) {
  const c = $("fig8").getContext("2d");
  const all = res.pairs.flatMap((p) => p.left_px.map(([, v], i) => [v, p.disparity_px[i]]));
  if (!all.length) { c.clearRect(0, 0, c.canvas.width, c.canvas.height); return; }
  const vs = all.map((a) => a[0]), ds = all.map((a) => a[1]);
  const [sx, sy] = axes(c, ...extentOf(vs), ...extentOf(ds), "row v (px)", "disparity u_l − u_r (px)");
  res.pairs.forEach((p, k) => {
    c.fillStyle = res.seed_px ? $("sel-colour").value : PALETTE[k % PALETTE.length];
    p.left_px.forEach(([, v], i) => c.fillRect(sx(v) - 1, sy(p.disparity_px[i]) - 1, 2, 2));
  });
}

// The live dense cloud in 3-D, at most once a second (a frame's cloud is tens of thousands of points), one
// drawing at a time: two in flight could finish in either order and leave the note of one frame over the
// cloud (and data-frame) of another.
let liveCloudAt = 0, liveCloudFrame = -1, liveCloudBusy = false;
async function liveCloud(frame) {
  if (liveCloudBusy || frame === liveCloudFrame || Date.now() - liveCloudAt < 1000) return;
  liveCloudAt = Date.now(); liveCloudFrame = frame; liveCloudBusy = true;
  try {
    const c = await api("/api/live/cloud");
    $("live-cloud").dataset.frame = String(c.frame);         // with the note, which drawCloud3d sets at once
    await drawCloud3d($("live-cloud"), c, "depth", "live-cloud-note",
                      `of frame ${c.frame} (the pixels of live mode's grid the echo test supported beyond chance, ` +
                      "tested every 30th frame, whose answer has held since)");
  } catch (e) { $("live-cloud-note").textContent = "live cloud: " + e.message; }
  finally { liveCloudBusy = false; }
}

function plotDepth(history) {
  const c = $("depth-plot").getContext("2d");
  const pts = history.filter((h) => h[1] !== null);
  if (!pts.length) { c.clearRect(0, 0, c.canvas.width, c.canvas.height); return; }
  const ts = pts.map((p) => p[0]), zs = pts.map((p) => p[1]);
  const [sx, sy] = axes(c, ...extentOf(ts), ...extentOf(zs), "time (s)", "depth Z (mm)");
  c.strokeStyle = "#1e88e5"; c.beginPath();
  pts.forEach(([t, z], i) => (i ? c.lineTo(sx(t), sy(z)) : c.moveTo(sx(t), sy(z))));
  c.stroke();
}

canvas.addEventListener("dblclick", async (ev) => {
  if (state.live) return;
  const r = canvas.getBoundingClientRect();
  const u = (ev.clientX - r.left) * canvas.width / r.width - 0.5, v = (ev.clientY - r.top) * canvas.height / r.height - 0.5;
  setStatus("matching…", true);
  try {
    const res = await api("/api/match", matchBody([u, v]));
    if (res.seed_px) state.seed = res.seed_px;
    showResult(res);
  } catch (e) { setStatus(e.message); }
});

$("auto").addEventListener("click", async () => {
  setStatus("pairing every edge…", true);
  try { showResult(await api("/api/match", matchBody(null))); } catch (e) { setStatus(e.message); }
});

$("dense").addEventListener("click", async () => {
  setStatus("dense disparity…", true);
  try {
    const res = await api("/api/dense", { fast: $("dense-fast").checked, views: $("dense-views").checked,
                                          near_mm: Number($("dense-near").value), far_mm: Number($("dense-far").value) });
    state.denseMaps = null;              // the pointer reads no earlier run's values over this one's picture
    $("dense-map").src = res.disparity_png;
    $("dense-left").src = res.left_png || ""; $("dense-right").src = res.right_png || "";
    $("dense-disparity").textContent = fmt(res.median_disparity_px, 1, "px");
    $("dense-depth").textContent = fmt(res.median_z_mm, 1, "mm");
    $("dense-depth").dataset.mm = res.median_z_mm ?? "";
    state.denseMaps = await denseMaps(res.maps);
    await drawDisparityMap($("dense-disparity-map"), state.denseMaps);
    await drawDepthMap($("dense-depth-map"), state.denseMaps);
    for (const [id, url] of [["dense-left-zoom", res.left_png], ["dense-right-zoom", res.right_png]]) {
      if (url) await drawZoomableImage($(id), url); else $(id).hidden = true;
    }
    state.denseCloud = res.cloud;
    await drawCloud3d($("dense-cloud"), res.cloud, $("dense-cloud-colour").value);
    if (res.refused) setStatus(`dense disparity: no depth: ${res.refused}`);
    else if (res.trusted_pct > 0) setStatus(`dense disparity: ${res.answered_pct.toFixed(0)} % of the pixels answered, ` +
      `${res.trusted_pct.toFixed(0)} % supported beyond chance (the medians and the cloud are theirs)`, true);
    else setStatus(`dense disparity: ${res.mapped_pct.toFixed(0)} % of the pixels mapped, none answered: none supported ` +
      "beyond chance: no depth (too little texture in the working range?)");
  } catch (e) { setStatus(e.message); }
});

$("dense-cloud-colour").addEventListener("change", (e) => {
  if (state.denseCloud) drawCloud3d($("dense-cloud"), state.denseCloud, e.target.value);
});

// The dense run's maps at full resolution (GET /api/dense/map: float32, row by row): {shape, disparity, z,
// untrusted}, each a Float32Array (NaN where the map has no such value).
async function denseMaps(m) {
  const [h, w] = m.shape, out = { shape: m.shape };
  if (m.run === null) throw new Error("the image or the rig changed while dense ran: run it again");
  await Promise.all(m.names.map(async (name) => {
    const r = await fetch(`/api/dense/map?name=${name}&run=${m.run}`);
    if (!r.ok) throw new Error(`dense map ${name}: ${r.status} ${r.statusText}`);
    out[name] = new Float32Array(await r.arrayBuffer());
    if (out[name].length !== h * w) throw new Error(`dense map ${name}: ${out[name].length} values, not ${h} x ${w}`);
  }));
  return out;
}

// The disparity and depth under the pointer on the dense map (its pixel, at full resolution).
$("dense-map").addEventListener("mousemove", (ev) => {
  const g = state.denseMaps, img = ev.target;
  if (!g || !img.clientWidth) return;
  const [h, w] = g.shape;
  const u = Math.min(Math.floor(ev.offsetX / img.clientWidth * w), w - 1);
  const v = Math.min(Math.floor(ev.offsetY / img.clientHeight * h), h - 1);
  const z = g.z[v * w + u], d = g.disparity[v * w + u];
  const out = $("dense-pointer");
  out.dataset.mm = Number.isNaN(z) ? "" : z;
  out.textContent = Number.isNaN(z) ? `(${u}, ${v}): not supported beyond chance` :
    `(${u}, ${v}): ${d.toFixed(2)} px, Z ${z.toFixed(1)} mm`;
});

async function livePoll() {
  if (!state.live) return;
  try {
    const s = await api("/api/live/state");
    state.liveState = s;
    $("live-frame").textContent = s.frame ?? "–";
    $("live-fps").textContent = fmt(s.fps, 1, "");
    $("live-latency").textContent = fmt(s.latency_ms, 1, "ms");
    $("live-depth").textContent = fmt(s.depth_mm, 2, "mm");
    $("live-depth").dataset.mm = s.depth_mm ?? "";
    plotDepth(s.history || []);
    if (s.error) setStatus("live: " + s.error);
    else if (s.message && !s.tracked) setStatus("live: " + s.message);
    else setStatus("live", true);
    if (s.dense) {
      $("live-dense-z").textContent = fmt(s.dense.median_z_mm, 1, "mm");
      $("live-dense-z").dataset.mm = s.dense.median_z_mm ?? "";
      $("live-dense-z").dataset.frame = s.dense.frame;
      $("live-dense-ms").textContent = fmt(s.dense.latency_ms, 0, "ms");
      if (!s.dense.supported) setStatus("live dense: no depth, " + (s.dense.refusal ||
        "the scene's echo does not stand above chance") + " (its map in grey: no measurement)");
      $("live-dense-figure").hidden = false;
      $("live-dense-map").src = "/api/live/dense.png?t=" + Date.now();
      liveCloud(s.dense.frame);
    }
    showHealth(s.health);
    if (s.frame !== undefined) state.liveFrame = await loadImg("/api/live/frame.png?t=" + Date.now());
    draw();
    if (!s.running) { state.live = false; return; }
  } catch (e) { setStatus("live: " + e.message); }
  setTimeout(livePoll, 80);
}

// The rolling self-check (psvs.health.rolling): its verdict and figure, coloured, and the lines it said.
function showHealth(h) {
  const el = $("live-health");
  if (!h) { el.textContent = "off"; el.className = ""; el.title = ""; $("live-health-lines").textContent = ""; return; }
  el.dataset.verdict = h.verdict ?? "";
  el.className = h.verdict === "drifted" ? "bad" : h.verdict === "healthy" ? "good" : "";
  el.textContent = h.verdict === null ? "waiting for its first tiles"
    : `${h.verdict}` + (h.row_offset_rms_px === null ? "" : `, rows ${h.row_offset_rms_px.toFixed(2)} px RMS`)
      + ` (${h.cost_pct.toFixed(1)} % of the time)`;
  el.title = h.reason;
  $("live-health-lines").textContent = h.lines.join("\n");
}

$("live-start").addEventListener("click", async () => {
  try {
    await api("/api/live/start", { ...matchBody(state.seed), dense: $("live-dense").checked,
                                   check: $("live-check").checked });
    $("live-dense-figure").hidden = true;          // no map from an earlier run
    $("live-dense-map").removeAttribute("src");
    $("live-cloud").hidden = true; $("live-cloud-note").textContent = ""; liveCloudFrame = -1;
    for (const id of ["live-dense-z", "live-dense-ms"]) { $(id).textContent = "–"; delete $(id).dataset.mm; delete $(id).dataset.frame; }
    state.live = true; state.liveFrame = null;
    livePoll();
  } catch (e) { setStatus(e.message); }
});

$("live-stop").addEventListener("click", async () => {
  try { await api("/api/live/stop", {}); } catch (e) { setStatus(e.message); }
  state.live = false; draw();
});

const FIELD = ["top-left", "top", "top-right", "left", "centre", "right", "bottom-left", "bottom", "bottom-right"];
let capturing = false;

function showCoverage(covered) {
  const body = $("capture-field").querySelector("tbody");
  body.innerHTML = "";
  for (let r = 0; r < 3; r++) {
    const tr = document.createElement("tr");
    for (let c = 0; c < 3; c++) {
      const name = FIELD[3 * r + c], n = covered["field:" + name] || 0, td = document.createElement("td");
      td.textContent = n; td.title = name; td.dataset.bin = "field:" + name;
      if (n) td.className = "covered";
      tr.appendChild(td);
    }
    body.appendChild(tr);
  }
  for (const [id, kind, names] of [["capture-depth", "depth", ["near", "mid", "far"]],
                                   ["capture-tilt", "tilt", ["flat", "left", "right", "up", "down"]]]) {
    $(id).innerHTML = "";
    names.forEach((name) => {
      const span = document.createElement("span"), n = covered[kind + ":" + name] || 0;
      span.textContent = `${name} ${n}`; span.dataset.bin = kind + ":" + name;
      if (n) span.className = "covered";
      $(id).appendChild(span);
    });
  }
}

async function capturePoll() {
  try {
    const s = await api("/api/capture/state");
    if (s.views !== undefined) {
      $("capture-saved").textContent = `${s.saved} / ${s.views}`;
      $("capture-saved").dataset.n = s.saved;
      $("capture-frame-no").textContent = s.frame ?? "–";
      $("capture-status").textContent = s.status ?? "–";
      $("capture-distance").textContent = fmt(s.distance_mm, 0, "mm");
      $("capture-hint").textContent = s.complete ? "enough to calibrate" : (s.hint || "");
      $("capture-missing").textContent = s.complete ? `saved in ${s.folder}` : (s.missing ? "missing: " + s.missing : "");
      showCoverage(s.covered);
      const ol = $("capture-events");
      ol.innerHTML = "";
      s.events.forEach((line) => { const li = document.createElement("li"); li.textContent = line; ol.appendChild(li); });
      ol.scrollTop = ol.scrollHeight;
      if (s.frame !== undefined) $("capture-image").src = "/api/capture/frame.png?t=" + Date.now();
      document.body.dataset.captureComplete = s.complete ? "1" : "";
    }
    if (s.error) setStatus("capture: " + s.error);
    if (!s.running) { capturing = false; return; }
  } catch (e) { setStatus("capture: " + e.message); }
  if (capturing) setTimeout(capturePoll, 250);
}

$("capture-start").addEventListener("click", async () => {
  try {
    await api("/api/capture/start", { views: Number($("capture-views").value), near_mm: Number($("capture-near").value),
                                      far_mm: Number($("capture-far").value) });
    state.live = false;                            // the capture reads the source now
    capturing = true; setStatus("capturing: show the card", true);
    capturePoll();
  } catch (e) { setStatus("capture: " + e.message); }
});

$("capture-stop").addEventListener("click", async () => {
  try { await api("/api/capture/stop", {}); } catch (e) { setStatus(e.message); }
  capturing = false; capturePoll();
});

// The complex image at full resolution, zoomable (its grey level and pixel under the pointer).
$("image-zoom-open").addEventListener("click", async () => {
  const blob = await (await fetch("/api/image.png?t=" + Date.now())).blob();
  const url = await new Promise((ok) => { const r = new FileReader(); r.onload = () => ok(r.result); r.readAsDataURL(blob); });
  await drawZoomableImage($("image-zoom"), url);
});

// Open image…: one file, or several (a folder's frames, in name order) to step through with ◀ ▶; each shown
// image is sent to the server (POST /api/upload), which reads the format from its bytes. Local files only.
const images = { files: [], k: 0 };

async function showImageFile(file) {
  // a type the browser does not know is sent as PNM's
  const type = state.uploadTypes.includes(file.type) ? file.type : "image/x-portable-anymap";
  const r = await fetch("/api/upload", { method: "POST", headers: { "Content-Type": type }, body: file });
  const data = await r.json().catch(() => ({}));
  if (!r.ok) { setStatus("upload: " + (data.detail || r.status)); $("header-status").textContent = $("status").textContent; return; }
  state.result = null; $("source").textContent = "image: " + file.name; $("header-status").textContent = "";
  await loadImage(); schedulePreview();
}

async function stepImages(by) {
  const n = images.files.length;
  if (!n) return;
  images.k = (images.k + by + n) % n;
  $("image-index").textContent = ` ${images.k + 1} of ${n} `;
  $("image-nav").hidden = n < 2;
  await showImageFile(images.files[images.k]);
}

$("upload").addEventListener("change", async (ev) => {
  const files = [...ev.target.files].sort((a, b) => a.name.localeCompare(b.name, undefined, { numeric: true }));
  if (!files.length) return;
  images.files = files; images.k = 0;
  await stepImages(0);
});
$("image-prev").addEventListener("click", () => stepImages(-1));
$("image-next").addEventListener("click", () => stepImages(1));

["filter", "filter-size", "binarise", "level", "edges"].forEach((id) => $(id).addEventListener("change", schedulePreview));
["show-edges", "sel-colour", "twin-colour"].forEach((id) => $(id).addEventListener("input", draw));

// Alignment panel (POST /api/adjust, docs/mount.md): the guide's turns, and the twins' row offset before and
// after them as two heat maps on one symmetric colour scale.
const adjust = { res: null };

function offsetColour(x, limit) {
  // diverging: blue (negative) - white (0) - red (positive); |x| >= limit saturated
  const t = Math.max(-1, Math.min(1, x / limit)), w = [247, 247, 247];
  const end = t < 0 ? [33, 102, 172] : [178, 24, 43], a = Math.abs(t);
  return `rgb(${w.map((c, i) => Math.round(c + (end[i] - c) * a)).join(",")})`;
}

function mapCells(depths, mode) {
  // one cell per grid pixel: at one depth, or the signed offset of largest |offset| over the depths
  const chosen = mode === "max" ? depths : depths.filter((d) => String(d.z_mm) === mode);
  const cells = new Map();
  chosen.forEach((d) => d.u_px.forEach((u, i) => {
    const key = `${u.toFixed(2)},${d.v_px[i].toFixed(2)}`, x = d.offset_px[i];
    const c = cells.get(key) || { u: u, v: d.v_px[i], x: null, weighed: false };
    if (x !== null && (c.x === null || Math.abs(x) > Math.abs(c.x))) c.x = x;
    c.weighed = c.weighed || d.weighed[i];
    cells.set(key, c);
  }));
  return [...cells.values()];
}

function gridStep(values) {
  const s = [...new Set(values.map((x) => x.toFixed(2)))].map(Number).sort((a, b) => a - b);
  return s.length > 1 ? Math.min(...s.slice(1).map((x, i) => x - s[i])) : 1;
}

function drawHeatmap(id, cells, size, limit) {
  const c = $(id), g = c.getContext("2d"), scale = c.width / size[0];
  c.height = Math.round(c.width * size[1] / size[0]);
  g.clearRect(0, 0, c.width, c.height);
  const du = gridStep(cells.map((p) => p.u)) * scale, dv = gridStep(cells.map((p) => p.v)) * scale;
  cells.forEach((p) => {
    const x = (p.u + 0.5) * scale - du / 2, y = (p.v + 0.5) * scale - dv / 2;
    g.fillStyle = p.x === null ? "#78909c" : offsetColour(p.x, limit);
    g.fillRect(x + 0.5, y + 0.5, du - 1, dv - 1);
    if (!p.weighed && p.x !== null) { g.strokeStyle = "#000"; g.strokeRect(x + 1, y + 1, du - 2, dv - 2); }
  });
}

function drawLegend(limit) {
  const c = $("adjust-legend"), g = c.getContext("2d"), m = 30, w = c.width - 2 * m;
  g.clearRect(0, 0, c.width, c.height);
  for (let i = 0; i < w; i++) { g.fillStyle = offsetColour((2 * i / (w - 1) - 1) * limit, limit); g.fillRect(m + i, 2, 1, 14); }
  g.strokeStyle = "#444"; g.strokeRect(m, 2, w, 14); g.fillStyle = "#444"; g.font = "11px sans-serif";
  [-1, -0.5, 0, 0.5, 1].forEach((f) => {
    const label = (f * limit).toFixed(limit < 2 ? 2 : 1) + (f === 1 ? " px" : "");
    g.fillText(label, m + (f + 1) / 2 * w - 10, 30);
  });
}

function drawAdjustMaps() {
  const res = adjust.res;
  if (!res) return;
  const mode = $("adjust-depth").value, size = res.maps.image_size_px;
  const before = mapCells(res.maps.before, mode), after = mapCells(res.maps.after, mode);
  const all = before.concat(after).filter((p) => p.x !== null).map((p) => Math.abs(p.x));
  const limit = Math.max(0.1, ...all);
  drawHeatmap("adjust-before", before, size, limit);
  drawHeatmap("adjust-after", after, size, limit);
  drawLegend(limit);
  $("adjust-legend").dataset.limitPx = String(limit);
  const which = mode === "max" ? "each cell: the largest |offset| over the depths " +
    res.maps.before.map((d) => d.z_mm).join(", ") + " mm, with its sign" : `each cell: the offset at ${mode} mm`;
  $("adjust-map-note").textContent = `Twins' row offset (v_left − v_right minus the design's, px) at the left ` +
    `view's pixel grid, over the image (${size[0]} × ${size[1]} px); ${which}. Both maps share the colour scale ` +
    `±${limit.toFixed(2)} px; grey: a view misses the point; outlined: not weighed by the guide.`;
}

function showAdjust(res) {
  adjust.res = res;
  const tbody = $("adjust-turns").querySelector("tbody"), g = res.guide;
  tbody.innerHTML = "";
  res.table.forEach((row, k) => {
    const tr = document.createElement("tr");
    [row.mirror, row.screw, row.trims, row.deg_per_turn.toFixed(3), row.turn].forEach((text) => {
      const td = document.createElement("td"); td.textContent = text; tr.appendChild(td);
    });
    tr.lastChild.className = "turn"; tr.lastChild.dataset.turns = String(g.turns[k].turns);
    tbody.appendChild(tr);
  });
  for (const [id, value] of [["adjust-before-max", g.row_offset_before_px.max], ["adjust-before-rms", g.row_offset_before_px.rms],
                             ["adjust-after-max", g.row_offset_after_px.max], ["adjust-after-rms", g.row_offset_after_px.rms]]) {
    $(id).textContent = fmt(value, 2, "px"); $(id).dataset.px = String(value);
  }
  $("adjust-null").textContent = res.null_space_text.join(" ");
  const sel = $("adjust-depth"), mode = sel.value;
  fillSelect(sel, [["max", "largest |offset| over the depths"], ...res.maps.before.map((d) => [String(d.z_mm), `at ${d.z_mm} mm`])]);
  sel.value = [...sel.options].some((o) => o.value === mode) ? mode : "max";
  drawAdjustMaps();
}

function fillSelect(sel, options) {
  sel.replaceChildren(...options.map(([value, text]) => { const o = document.createElement("option");
                                                          o.value = value; o.textContent = text; return o; }));
}

function adjustStatus(text, ok) { const s = $("adjust-status"); s.textContent = text || ""; s.className = ok ? "ok" : ""; }

$("adjust-run").addEventListener("click", async () => {
  const rig = $("adjust-rig").files[0], mount = $("adjust-mount").files[0];
  if (!rig) { adjustStatus("pick the calibrated rig file (psvs calibrate -o)"); return; }
  document.body.dataset.adjustDone = "";
  adjustStatus("finding the turns…", true);
  try {
    const body = { calibrated: await rig.text(), near_mm: Number($("adjust-near").value),
                   far_mm: Number($("adjust-far").value) };
    if ($("adjust-design").value) body.design = $("adjust-design").value;
    if (mount) body.mount = await mount.text(); else body.pitch_mm = Number($("adjust-pitch").value);
    const res = await api("/api/adjust", body);
    showAdjust(res);
    adjustStatus(`${rig.name} on the seats of ${mount ? mount.name : res.design + "'s mirrors"}: ${res.guide.points} ` +
                 `field points over ${res.guide.near_mm}-${res.guide.far_mm} mm`, true);
    document.body.dataset.adjustDone = "1";
  } catch (e) { adjustStatus("alignment: " + e.message); document.body.dataset.adjustDone = "error"; }
});

$("adjust-depth").addEventListener("change", drawAdjustMaps);

async function adjustInit() {
  const d = await api("/api/adjust/designs");
  fillSelect($("adjust-design"), [["", `served: ${d.served}`], ...d.shipped.map((n) => [n, n])]);
  $("adjust-pitch").value = d.pitch_mm;
  await workflowInit(d.served, d.shipped);       // workflow.js: the Design step's rig choice
}
