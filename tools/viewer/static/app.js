// The operator's page: pulls the newest state (long poll), with the newest camera image in
// the same reply when it is not the one shown. A slow browser simply asks less often; the
// server never queues states for it.
"use strict";

const $ = (id) => document.getElementById(id);
let version = 0;
let state = null;
let imageSeq = -1;
let staticMap = null;  // the robot's map (/api/map): its walls as runs of cells
let mapLoading = false;
// how the map draws a laser's returns and the people it sees (people with no image box)
const SCAN_COLOUR = "#d8c27a", LASER_PERSON_COLOUR = "#a0e8ff";

async function loadMap() {
  mapLoading = true;
  try {
    const res = await fetch("/api/map", { cache: "no-store" });
    if (res.ok) { staticMap = await res.json(); if (state) drawMap(); }
  } catch (err) {
    // the next state asks again
  } finally {
    mapLoading = false;
  }
}

function setConnection(ok, text) {
  const el = $("connection");
  el.textContent = text;
  el.className = ok ? "ok" : "down";
}

async function pull() {
  for (;;) {
    try {
      const res = await fetch(`/api/state?after=${version}&image=${imageSeq}`, { cache: "no-store" });
      if (!res.ok) throw new Error(`HTTP ${res.status}`);
      const next = await res.json();
      if (next.version !== undefined) {
        version = next.version;
        state = next;
        if (next.jpeg && next.image) showImage(next.image.seq, next.jpeg);
        const wanted = next.static_map ? next.static_map.version : null;
        if (wanted !== null && (!staticMap || staticMap.version !== wanted) && !mapLoading) loadMap();
        render();
      }
      setConnection(true, "live");
    } catch (err) {
      setConnection(false, `no connection (${err.message}), retrying`);
      await new Promise((r) => setTimeout(r, 1000));
    }
  }
}

function fmt(v, digits = 1) {
  return v === null || v === undefined ? "–" : Number(v).toFixed(digits);
}

function row(cells, attrs = {}) {
  const tr = document.createElement("tr");
  for (const [k, v] of Object.entries(attrs)) tr.setAttribute(k, v);
  for (const c of cells) {
    const td = document.createElement("td");
    if (c instanceof Node) td.appendChild(c); else td.textContent = c;
    tr.appendChild(td);
  }
  return tr;
}

function swatch(colour, text) {
  const span = document.createElement("span");
  const dot = document.createElement("span");
  dot.className = "swatch";
  dot.style.background = colour;
  span.appendChild(dot);
  span.appendChild(document.createTextNode(text));
  return span;
}

function render() {
  $("map-frame").textContent = `frame ${state.map_frame}`;
  $("camera-name").textContent = state.camera;
  const mode = state.appearance_available === false ? "   position only (no embeddings)" : "";
  const confirmed = state.tracks.filter((t) => t.status === "confirmed").length;
  $("summary").textContent = `${confirmed} confirmed of ${state.tracks.length} tracks${mode}`;
  renderTracks();
  renderDecisions();
  renderStages();
  renderNodes();
  drawMap();
  drawOverlay();
}

function renderTracks() {
  const body = $("tracks").tBodies[0];
  body.replaceChildren(...state.tracks.map((t) => row(
    [swatch(t.colour, String(t.id)), fmt(t.x, 2), fmt(t.y, 2), fmt(Math.hypot(t.vx, t.vy), 2), t.status, t.hits, fmt(t.age_s)],
    { "data-track-id": t.id })));
}

// Why the tracker gave its recent IDs: one line each, as the tracker logs them.
function renderDecisions() {
  const list = $("id-decisions");
  const items = (state.id_decisions || []).map((d) => {
    const li = document.createElement("li");
    li.dataset.outcome = d.outcome;
    li.dataset.id = d.id;
    li.textContent = `${fmt(d.age_s, 0)} s ago: ${d.text}`;
    return li;
  });
  if (!items.length) {
    const li = document.createElement("li");
    li.className = "none";
    li.textContent = "none yet (a returning or new person's ID is explained here)";
    items.push(li);
  }
  list.replaceChildren(...items);
}

function renderStages() {
  const body = $("stages").tBodies[0];
  body.replaceChildren(...state.stages.map((s) => row(
    [s.name, s.count, fmt(s.rate_hz), fmt(s.latency_p50_ms), fmt(s.latency_p95_ms)], { "data-stage": s.name })));
}

function renderNodes() {
  const body = $("nodes").tBodies[0];
  body.replaceChildren(...state.nodes.map((n) => {
    const h = document.createElement("span");
    h.className = n.health;
    h.textContent = n.health + (n.error ? `: ${n.error}` : "");
    return row([n.name, h, n.host ?? "", n.received ?? "", n.published ?? "", n.dropped ?? "", n.invalid ?? ""],
      { "data-node": n.name, "data-health": n.health });
  }));
}

// A canvas drawn at its displayed size (in device pixels): the layout decides its size.
function fitCanvas(cv) {
  const dpr = window.devicePixelRatio || 1;
  const w = Math.max(1, Math.round(cv.clientWidth * dpr)), h = Math.max(1, Math.round(cv.clientHeight * dpr));
  if (cv.width !== w || cv.height !== h) { cv.width = w; cv.height = h; }
  const ctx = cv.getContext("2d");
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  return [ctx, cv.clientWidth || 1, cv.clientHeight || 1];
}

function drawMap() {
  const [ctx, W, H] = fitCanvas($("map"));
  ctx.clearRect(0, 0, W, H);
  // fit every track, trail point, laser person and the robot, at least 6 m across (not the scans' walls)
  const xs = [], ys = [];
  const scans = state.scans || [], laserPeople = state.laser_people || [];
  for (const t of state.tracks) { xs.push(t.x); ys.push(t.y); for (const [x, y] of t.trail) { xs.push(x); ys.push(y); } }
  for (const p of laserPeople) { xs.push(p.x); ys.push(p.y); }
  if (state.robot) { xs.push(state.robot.x); ys.push(state.robot.y); }
  if (!xs.length) { xs.push(0); ys.push(0); }
  const cx = (Math.min(...xs) + Math.max(...xs)) / 2, cy = (Math.min(...ys) + Math.max(...ys)) / 2;
  const span = Math.max(6, Math.max(...xs) - Math.min(...xs) + 2, (Math.max(...ys) - Math.min(...ys) + 2) * W / H);
  const scale = W / span;
  const px = (x) => W / 2 + (x - cx) * scale, py = (y) => H / 2 - (y - cy) * scale;
  ctx.strokeStyle = "#262b33"; ctx.lineWidth = 1;
  for (let g = Math.floor(cx - span); g <= cx + span; g++) { ctx.beginPath(); ctx.moveTo(px(g), 0); ctx.lineTo(px(g), H); ctx.stroke(); }
  for (let g = Math.floor(cy - span); g <= cy + span; g++) { ctx.beginPath(); ctx.moveTo(0, py(g)); ctx.lineTo(W, py(g)); ctx.stroke(); }
  const m = staticMap;
  if (m && m.runs && m.frame_id === state.map_frame) {  // the walls, under everything else
    const [ox, oy, yaw] = m.origin;
    ctx.save(); ctx.translate(px(ox), py(oy)); ctx.rotate(-yaw); ctx.scale(scale, -scale);
    ctx.fillStyle = "#5f6b7a";
    const res = m.resolution, seam = 0.6 / scale;  // a little overlap: no hairline between rows
    for (const [r, c0, c1] of m.runs) ctx.fillRect(c0 * res, r * res, (c1 - c0) * res + seam, res + seam);
    ctx.restore();
  }
  // each laser's newest scan: its returns as small squares, in the map through the transforms
  ctx.fillStyle = SCAN_COLOUR;
  for (const s of scans) {
    const p = s.points;
    for (let i = 0; i + 1 < p.length; i += 2) ctx.fillRect(px(p[i]) - 1.5, py(p[i + 1]) - 1.5, 3, 3);
  }
  const legend = ["grid 1 m"];
  if (m && m.runs) legend.push("grey: the robot's map");
  if (scans.length) legend.push(`sand: ${scans.map((s) => s.error ? `laser ${s.laser} (${s.error})` : `laser ${s.laser}`).join(", ")}`);
  if (laserPeople.length) legend.push("rings: people the laser sees");
  ctx.fillStyle = "#667"; ctx.font = "11px sans-serif";
  ctx.fillText(legend.join("; "), 6, H - 6);
  $("map").dataset.legend = legend.join("; ");
  if (state.robot) {
    const r = state.robot, x = px(r.x), y = py(r.y);
    ctx.save(); ctx.translate(x, y); ctx.rotate(-r.yaw);
    ctx.fillStyle = "#8ab4f8"; ctx.beginPath(); ctx.moveTo(14, 0); ctx.lineTo(-9, 8); ctx.lineTo(-9, -8); ctx.closePath(); ctx.fill();
    ctx.restore();
    ctx.fillStyle = "#8ab4f8"; ctx.fillText("robot", x + 10, y + 16);
  }
  // people with no image box (a laser's): a ring on the map, under the tracks
  ctx.strokeStyle = LASER_PERSON_COLOUR; ctx.fillStyle = LASER_PERSON_COLOUR; ctx.lineWidth = 2;
  for (const p of laserPeople) {
    ctx.beginPath(); ctx.arc(px(p.x), py(p.y), 6, 0, 2 * Math.PI); ctx.stroke();
    ctx.beginPath(); ctx.arc(px(p.x), py(p.y), 2, 0, 2 * Math.PI); ctx.fill();
  }
  for (const t of state.tracks) {
    ctx.strokeStyle = t.colour; ctx.lineWidth = 2; ctx.globalAlpha = 0.6;
    ctx.beginPath();
    t.trail.forEach(([x, y], i) => (i ? ctx.lineTo(px(x), py(y)) : ctx.moveTo(px(x), py(y))));
    ctx.stroke(); ctx.globalAlpha = 1;
    ctx.fillStyle = t.colour; ctx.beginPath(); ctx.arc(px(t.x), py(t.y), 7, 0, 2 * Math.PI); ctx.fill();
    ctx.beginPath(); ctx.moveTo(px(t.x), py(t.y)); ctx.lineTo(px(t.x + t.vx), py(t.y + t.vy)); ctx.stroke();
    ctx.fillStyle = "#fff"; ctx.font = "bold 13px sans-serif"; ctx.fillText(String(t.id), px(t.x) + 9, py(t.y) - 9);
  }
}

function showImage(seq, jpeg) {
  const img = $("camera");
  img.onload = img.onerror = () => drawOverlay();
  imageSeq = seq;
  img.src = `data:image/jpeg;base64,${jpeg}`;
}

// The camera image is shown whole (object-fit: contain) in its box; the overlay covers the box
// and draws in image pixels through the same scale and offset. Labels stay inside the image.
function drawOverlay() {
  if (!state || !state.image) return;
  const [ctx, W, H] = fitCanvas($("overlay"));
  ctx.clearRect(0, 0, W, H);
  const iw = state.image.width, ih = state.image.height;
  const k = Math.min(W / iw, H / ih), ox = (W - iw * k) / 2, oy = (H - ih * k) / 2;
  ctx.save();
  ctx.translate(ox, oy); ctx.scale(k, k);
  ctx.lineWidth = 2 / k;  // 2 CSS pixels, and labels 13, whatever the image's scale
  const size = 13 / k;
  ctx.font = `bold ${size}px sans-serif`; ctx.textBaseline = "top";
  for (const b of state.boxes) {
    const [x1, y1, x2, y2] = b.bbox;
    ctx.strokeStyle = b.colour; ctx.strokeRect(x1, y1, x2 - x1, y2 - y1);
    if (b.id !== null) {
      const text = `ID ${b.id}`, w = ctx.measureText(text).width, pad = 2 / k;
      // above the box when it fits, else inside its top; always within the image
      const x = clamp(x1, 0, iw - w - 2 * pad), y = clamp(y1 - size - 2 * pad, 0, ih - size - 2 * pad);
      ctx.fillStyle = "rgba(16, 18, 22, 0.7)"; ctx.fillRect(x, y, w + 2 * pad, size + 2 * pad);
      ctx.fillStyle = b.colour; ctx.fillText(text, x + pad, y + pad);
    }
  }
  ctx.restore();
}

function clamp(v, lo, hi) {
  return Math.min(Math.max(v, lo), Math.max(lo, hi));
}

window.addEventListener("resize", () => { if (state) { drawMap(); drawOverlay(); } });

pull();
