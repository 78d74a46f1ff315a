"use strict";
// The rig in 3-D (GET /api/rig3d, psvs.optics.layout3d), drawn with plotly.js (served by psvs from the
// installed plotly package). Plot axes: X right, Z (depth) away, up = -Y (image rows grow downward).

const RIG3D_COLOURS = { left: "#d32f2f", right: "#00838f", glass: "#64b5f6", camera: "#212121" };

// [min, max] of an array of numbers, however long (Math.min(...a) passes every value as an argument: a mesh's
// vertices or a frame's edge pixels can be more than a browser takes).
function extentOf(values) {
  let lo = Infinity, hi = -Infinity;
  for (const v of values) { if (v < lo) lo = v; if (v > hi) hi = v; }
  return [lo, hi];
}

function rig3dPoint(p) { return [p[0], p[2], -p[1]]; }

const rig3dState = { layout: null };     // the served rig's layout, as last drawn

// The rig's layout with a mount's mesh (POST /api/mount/mesh) round it, at true scale.
// The mount's mesh (frame C, mm) as a plotly trace.
function mountTrace(mesh) {
  const q = mesh.vertices.map(rig3dPoint);
  return { type: "mesh3d", name: `${mesh.name} (${mesh.volume_cm3} cm³)`, x: q.map((p) => p[0]),
           y: q.map((p) => p[1]), z: q.map((p) => p[2]), i: mesh.triangles.map((t) => t[0]),
           j: mesh.triangles.map((t) => t[1]), k: mesh.triangles.map((t) => t[2]), color: "#b0bec5",
           opacity: 0.5, flatshading: true, hoverinfo: "name", showlegend: true };
}

function drawMount3d(el, layout, mesh) {
  el.hidden = false;
  if (typeof Plotly === "undefined") return Promise.resolve();
  const q = mesh.vertices.map(rig3dPoint);
  const trace = mountTrace(mesh);
  // the view holds the mount and the glasses, 20 mm spare, at true scale
  const pts = [...q, ...layout.glasses.flatMap((g) => g.corners_mm).map(rig3dPoint)];
  const ranges = [0, 1, 2].map((k) => extentOf(pts.map((p) => p[k]))).map(([lo, hi]) => [lo - 20, hi + 20]);
  const span = ranges.map((r) => r[1] - r[0]), top = Math.max(...span);
  return drawRig3d(el, layout)
    .then(() => Plotly.addTraces(el, trace))
    .then(() => Plotly.relayout(el, { "scene.aspectmode": "manual", "scene.xaxis.range": ranges[0],
                                      "scene.yaxis.range": ranges[1], "scene.zaxis.range": ranges[2],
                                      "scene.aspectratio": { x: span[0] / top, y: span[1] / top, z: span[2] / top } }))
    .then(() => { el.dataset.ready = "1"; el.dataset.triangles = String(mesh.triangles.length); });
}

// Polylines (arrays of points) as one line trace, NaN-separated.
function rig3dLines(polylines, name, colour, width, extra = {}) {
  const x = [], y = [], z = [];
  for (const line of polylines) {
    for (const p of line) { const q = rig3dPoint(p); x.push(q[0]); y.push(q[1]); z.push(q[2]); }
    x.push(null); y.push(null); z.push(null);
  }
  return { type: "scatter3d", mode: "lines", name, x, y, z, line: { color: colour, width }, hoverinfo: "name",
           ...extra };
}

function rig3dGlass(g) {
  const c = g.corners_mm.map(rig3dPoint);
  return { type: "mesh3d", name: `${g.label} (${g.sized})`, x: c.map((p) => p[0]), y: c.map((p) => p[1]),
           z: c.map((p) => p[2]), i: [0, 0], j: [1, 2], k: [2, 3], color: RIG3D_COLOURS.glass, opacity: 0.45,
           hoverinfo: "name", showlegend: g.name === "M1" };
}

function rig3dMarkers(points, names, colour, symbol) {
  const q = points.map(rig3dPoint);
  return { type: "scatter3d", mode: "markers+text", x: q.map((p) => p[0]), y: q.map((p) => p[1]),
           z: q.map((p) => p[2]), text: names, textposition: "top center", name: names.join(", "),
           marker: { size: 4, color: colour, symbol }, hoverinfo: "text", showlegend: false };
}

// Draw the layout into the element `el`; returns plotly's promise.
function drawRig3d(el, layout) {
  const traces = layout.glasses.map(rig3dGlass);
  traces.push(rig3dLines(layout.glasses.map((g) => [...g.corners_mm, g.corners_mm[0]]), "glass edges",
                         "#1565c0", 2, { showlegend: false }));
  if (layout.designed) {          // a build: where its design puts each glass, beside where it is
    traces.push(rig3dLines(layout.designed.map((g) => [...g.corners_mm, g.corners_mm[0]]), "glasses as designed",
                           "#ef6c00", 2, { line: { color: "#ef6c00", width: 2, dash: "dot" } }));
  }
  for (const view of ["left", "right"]) {
    traces.push(rig3dLines(layout.rays[view], `${view} view's field rays`, RIG3D_COLOURS[view], 2));
    const fields = ["near", "far"].map((k) => layout.field[view][k]).filter((f) => f);
    traces.push(rig3dLines(fields.map((f) => [...f, f[0]]), `${view} view's field at ` +
                           `${layout.range_mm[0]} and ${layout.range_mm[1]} mm`, RIG3D_COLOURS[view], 4,
                           { line: { color: RIG3D_COLOURS[view], width: 4, dash: "dash" } }));
  }
  traces.push(rig3dMarkers([layout.camera, layout.virtual.left, layout.virtual.right],
                           ["camera O", "virtual left O1", "virtual right O2"], RIG3D_COLOURS.camera, "diamond"));
  const plotLayout = {
    margin: { l: 0, r: 0, t: 0, b: 0 }, showlegend: true,
    legend: { orientation: "h", x: 0, y: 0, font: { size: 10 }, bgcolor: "rgba(255,255,255,0.7)" },
    scene: { xaxis: { title: { text: "X (mm)" } }, yaxis: { title: { text: "Z (mm)" } },
             zaxis: { title: { text: "-Y (mm)" } }, camera: { eye: { x: 0.5, y: -1.2, z: 1.5 } } },
  };
  return Plotly.newPlot(el, traces, plotLayout, { displaylogo: false, responsive: true })
    .then(() => rig3dExtent(el, layout, "glasses"));
}

// Show the glasses (the box round the camera, the glasses and the virtual cameras, 20 mm spare) or the whole
// working range (every ray to the far depth), at true scale either way.
function rig3dExtent(el, layout, which) {
  if (which === "range") {
    return Plotly.relayout(el, { "scene.aspectmode": "data", "scene.xaxis.autorange": true,
                                 "scene.yaxis.autorange": true, "scene.zaxis.autorange": true });
  }
  const pts = [layout.camera, layout.virtual.left, layout.virtual.right,
               ...layout.glasses.flatMap((g) => g.corners_mm)].map(rig3dPoint);
  const ranges = [0, 1, 2].map((k) => extentOf(pts.map((p) => p[k]))).map(([lo, hi]) => [lo - 20, hi + 20]);
  const span = ranges.map((r) => r[1] - r[0]), top = Math.max(...span);
  return Plotly.relayout(el, {
    "scene.aspectmode": "manual", "scene.xaxis.range": ranges[0], "scene.yaxis.range": ranges[1],
    "scene.zaxis.range": ranges[2],
    "scene.aspectratio": { x: span[0] / top, y: span[1] / top, z: span[2] / top },
  });
}

async function rig3dInit() {
  const el = document.getElementById("rig3d");
  if (typeof Plotly === "undefined") {
    document.getElementById("rig3d-note").textContent = "3-D views need the plotly package (pip install plotly).";
    return;
  }
  const near = Number(document.getElementById("rig3d-near").value), far = Number(document.getElementById("rig3d-far").value);
  const call = (rig3dState.calls = (rig3dState.calls || 0) + 1);      // a later call's answer wins, whenever
  const r = await fetch(`/api/rig3d?near_mm=${near}&far_mm=${far}`);  // the earlier's arrives
  const layout = await r.json().catch(() => ({}));
  if (call !== rig3dState.calls) return;
  if (!r.ok) {            // the rest of the page works without it
    document.getElementById("rig3d-note").textContent = "no 3-D view of this rig: " + (layout.detail || r.status);
    return;
  }
  rig3dState.layout = layout;
  await drawRig3d(el, layout);
  if (call !== rig3dState.calls) return;
  el.dataset.range = `${near}-${far}`;
  document.getElementById("rig3d-extent").onchange = (e) => rig3dExtent(el, layout, e.target.value);
  const sized = layout.glasses.some((g) => g.sized !== "rig file");
  document.getElementById("rig3d-note").textContent =
    "Drag to turn, scroll to zoom. The glasses " + (sized ? "are drawn at the camera field's footprint (the rig " +
    "file gives no sizes: psvs design sizes them)" : "as the rig file sizes them") +
    (layout.designed ? ", where the build has them (orange dots: where its design puts them)" : "") +
    "; rays traced through the " +
    "exact optics, M1's plate refraction included.";
  el.dataset.ready = "1";
}

// Frame C's axes at O (X along the image's columns, Y its rows, Z the optical axis), a fifth of the cloud's
// median depth long (100 mm without points), each named: the frame the cloud's millimetres are in.
function cloudFrameAxes(q) {
  const depths = q.map((p) => p[1]).sort((a, b) => a - b);
  const len = depths.length ? Math.max(10, 0.2 * depths[Math.floor(depths.length / 2)]) : 100;
  return [["X", [len, 0, 0], "#c62828"], ["Y", [0, len, 0], "#2e7d32"], ["Z", [0, 0, len], "#1565c0"]].map(
    ([axis, end, colour]) => rig3dLines([[[0, 0, 0], end]], `frame C: ${axis}`, colour, 5,
                                        { showlegend: false, hoverinfo: "name" }));
}

// A dense result's point cloud (frame C, mm), coloured by depth with a colour bar, with the camera's centre O
// and frame C's axes;
// an empty cloud clears the view and says so. ``what`` says what its points are (a still's: the trusted pixels',
// supported beyond chance; live mode's: those its latest echo test supported, held since), in the note ``noteId``.
function drawCloud3d(el, cloud, colour = "depth", noteId = "dense-cloud-note", what = "supported beyond chance") {
  el.hidden = false;
  if (typeof Plotly === "undefined") return Promise.resolve();
  const q = cloud.points_mm.map(rig3dPoint);
  const note = document.getElementById(noteId);
  note.textContent = q.length ? `${cloud.of_points} points ${what}` +
    (q.length < cloud.of_points ? `, ${q.length} drawn` : "") + "; drag to turn, scroll to zoom." :
    `no point ${what}: nothing to draw`;
  const traces = [
    { type: "scatter3d", mode: "markers", name: "dense points", x: q.map((p) => p[0]), y: q.map((p) => p[1]),
      z: q.map((p) => p[2]), marker: colour === "grey" ?
        { size: 1.5, color: cloud.grey.map((g) => `rgb(${g},${g},${g})`) } :
        { size: 1.5, color: q.map((p) => p[1]), colorscale: "Viridis", colorbar: { title: { text: "Z (mm)" }, thickness: 12 } },
      hovertemplate: "Z %{y:.1f} mm<extra></extra>" },
    rig3dMarkers([[0, 0, 0]], ["camera O"], RIG3D_COLOURS.camera, "diamond"),
    ...cloudFrameAxes(q),
  ];
  // a fixed height: redrawn while live mode runs, an autosized plot can collapse to its container's 0 px
  const layout = { margin: { l: 0, r: 0, t: 0, b: 0 }, showlegend: false, height: 450,
                   scene: { aspectmode: "data", xaxis: { title: { text: "X (mm)" } },
                            yaxis: { title: { text: "Z (mm)" } }, zaxis: { title: { text: "-Y (mm)" } },
                            camera: { eye: { x: 0.6, y: -1.6, z: 0.8 } } } };
  return Plotly.react(el, traces, layout, { displaylogo: false, responsive: true })
    .then(() => { el.dataset.points = String(q.length); el.dataset.colour = colour; });
}

// A seam-tracking run (POST /api/robot/run) in the robot's base frame (mm, Z up): the seam points the sensor
// measured, the torch's path (grey in the run-in, red with the arc on), where it stopped, and the sensor's view.
function drawRobot3d(el, run) {
  el.hidden = false;
  if (typeof Plotly === "undefined") return Promise.resolve();
  const xyz = (pts) => ({ x: pts.map((p) => p[0]), y: pts.map((p) => p[1]), z: pts.map((p) => p[2]) });
  const runIn = run.tcp_mm.filter((_, i) => !run.welded[i]), welded = run.tcp_mm.filter((_, i) => run.welded[i]);
  const last = run.tcp_mm[run.tcp_mm.length - 1];
  const traces = [
    { type: "scatter3d", mode: "markers", name: "seam as the sensor measured it", ...xyz(run.seam_mm),
      marker: { size: 2, color: RIG3D_COLOURS.right } },
    { type: "scatter3d", mode: "lines", name: "torch tip, run-in", ...xyz(runIn), line: { color: "#9e9e9e", width: 4 } },
    { type: "scatter3d", mode: "lines", name: "torch tip, arc on", ...xyz(welded),
      line: { color: RIG3D_COLOURS.left, width: 6 } },
    { type: "scatter3d", mode: "markers+text", name: "stop", x: [last[0]], y: [last[1]], z: [last[2]], text: ["stop"],
      textposition: "top center", marker: { size: 4, color: RIG3D_COLOURS.camera, symbol: "square" }, showlegend: false },
  ];
  traces.push(...robotSensorTraces(run.sensor));
  const layout = { margin: { l: 0, r: 0, t: 0, b: 0 }, showlegend: true,
                   legend: { orientation: "h", x: 0, y: 0, font: { size: 10 }, bgcolor: "rgba(255,255,255,0.7)" },
                   scene: { aspectmode: "data", xaxis: { title: { text: "X (mm)" } }, yaxis: { title: { text: "Y (mm)" } },
                            zaxis: { title: { text: "Z (mm)" } }, camera: { eye: { x: 0.8, y: -1.4, z: 1.0 } } } };
  return Plotly.react(el, traces, layout, { displaylogo: false, responsive: true })
    .then(() => { el.dataset.ready = "1"; el.dataset.points = String(run.seam_mm.length);
                  el.dataset.sensor = run.sensor ? String(run.sensor.cycle) : ""; });
}

// The PSVS's view at the run's last cycle (POST /api/robot/run's `sensor`, base frame, mm): the camera, its
// light through the glasses to the work, and each view's field over the seam sensor's depths.
function robotSensorTraces(s) {
  if (!s) return [];
  const lines = (polys, name, colour, width, dash) => {
    const x = [], y = [], z = [];
    for (const line of polys) {
      for (const p of line) { x.push(p === null ? null : p[0]); y.push(p === null ? null : p[1]); z.push(p === null ? null : p[2]); }
      x.push(null); y.push(null); z.push(null);
    }
    return { type: "scatter3d", mode: "lines", name, x, y, z, hoverinfo: "name", line: { color: colour, width, dash } };
  };
  const out = [];
  for (const view of ["left", "right"]) {
    out.push(lines(s.rays[view], `${view} view's light (last cycle; mounting: ${s.mounting})`, RIG3D_COLOURS[view], 2,
                   "solid"));
    const fields = ["near", "far"].map((k) => s.field[view][k]).filter((f) => f);
    out.push(lines(fields.map((f) => [...f, f[0]]), `${view} view's field over the sensor's depths`,
                   RIG3D_COLOURS[view], 3, "dash"));
  }
  out.push({ type: "scatter3d", mode: "markers+text", name: "PSVS camera", x: [s.camera[0]], y: [s.camera[1]],
             z: [s.camera[2]], text: ["PSVS"], textposition: "top center", showlegend: false,
             marker: { size: 4, color: RIG3D_COLOURS.camera, symbol: "diamond" } });
  return out;
}

// A map (Float32Array, row by row, NaN where no value) as the rows a Plotly heat map takes (views, not copies).
function mapRows(a, shape) {
  const [h, w] = shape;
  return Array.from({ length: h }, (_, v) => a.subarray(v * w, (v + 1) * w));
}

// The dense result's left-view disparity at full resolution (every pixel of the map) as a zoomable heat map with
// a colour bar in px: the pixels the echo supports beyond chance in colour, those answered without that support
// in grey (the CLI's confidence 0), the disparity under the pointer.
function drawDisparityMap(el, g) {
  el.hidden = false;
  if (typeof Plotly === "undefined") return Promise.resolve();
  let untrusted = 0;
  for (const x of g.untrusted) if (!Number.isNaN(x)) untrusted += 1;
  const traces = [
    { type: "heatmap", z: mapRows(g.untrusted, g.shape), colorscale: [[0, "#bdbdbd"], [1, "#bdbdbd"]],
      showscale: false, hoverongaps: false, name: "not supported",
      hovertemplate: "(%{x}, %{y}): %{z:.2f} px, not supported beyond chance<extra></extra>" },
    { type: "heatmap", z: mapRows(g.disparity, g.shape), colorscale: "Portland", hoverongaps: false, name: "supported",
      colorbar: { title: { text: "d (px)" }, thickness: 14 }, hovertemplate: "(%{x}, %{y}): %{z:.2f} px<extra></extra>" },
  ];
  const layout = { margin: { l: 50, r: 10, t: 10, b: 40 }, dragmode: "zoom",
                   xaxis: { title: { text: "u (px)" }, constrain: "domain" },
                   yaxis: { title: { text: "v (px)" }, autorange: "reversed", scaleanchor: "x" } };
  return Plotly.react(el, traces, layout, { displaylogo: false, responsive: true })
    .then(() => { el.dataset.ready = "1"; el.dataset.untrusted = String(untrusted); });
}

// An image (a PNG data URL) at full resolution, zoomable: drag a box to zoom, double-click to zoom out.
function drawZoomableImage(el, url) {
  el.hidden = false;
  if (typeof Plotly === "undefined") return Promise.resolve();
  const layout = { margin: { l: 40, r: 10, t: 10, b: 30 }, dragmode: "zoom",
                   xaxis: { constrain: "domain" }, yaxis: { autorange: "reversed", scaleanchor: "x" } };
  return Plotly.react(el, [{ type: "image", source: url, hovertemplate: "(%{x}, %{y})<extra></extra>" }], layout,
                      { displaylogo: false, responsive: true }).then(() => { el.dataset.ready = "1"; });
}

// The dense result's depth map (the trusted pixels' Z, mm; every pixel of the map, blank where the echo does not
// support the answer) as a zoomable heat map with a colour bar in mm: drag a box to zoom, double-click to zoom
// out; the pixel and its Z under the pointer.
function drawDepthMap(el, g) {
  el.hidden = false;
  if (typeof Plotly === "undefined") return Promise.resolve();
  const trace = { type: "heatmap", z: mapRows(g.z, g.shape), colorscale: "Viridis",        // as the cloud's colours
                  colorbar: { title: { text: "Z (mm)" }, thickness: 14 }, hoverongaps: false,
                  hovertemplate: "(%{x}, %{y}): Z %{z:.1f} mm<extra></extra>" };
  const layout = { margin: { l: 50, r: 10, t: 10, b: 40 }, dragmode: "zoom",
                   xaxis: { title: { text: "u (px)" }, constrain: "domain" },
                   yaxis: { title: { text: "v (px)" }, autorange: "reversed", scaleanchor: "x" } };
  return Plotly.react(el, [trace], layout, { displaylogo: false, responsive: true })
    .then(() => { el.dataset.ready = "1"; el.dataset.cells = String(g.shape[0] * g.shape[1]); });
}
