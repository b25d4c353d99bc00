// The fleet ground station's page: polls /api/state, draws every vehicle on a top-down map (ENU: x right, y up)
// in its colour, sends commands to the selected vehicles or to all, and previews a plain-language mission on the
// map before its Fly button can send it (python/cufund/apps/gcs/fleet_server.py).
"use strict";
const token = new URLSearchParams(location.search).get("token") || "";
const $ = (id) => document.getElementById(id);
const state = { names: [], colours: {}, vehicles: {}, trails: {}, selected: new Set(), preview: null, events: 0, area: [] };
window.fleetGcs = { // for tests: the page's state and the map's transform (world [m] <-> canvas [px])
  state,
  toCanvas: (x, y) => (view ? [view.ox + view.sx * x, view.oy - view.sx * y] : null),
  fromCanvas: (cx, cy) => (view ? [(cx - view.ox) / view.sx, (view.oy - cy) / view.sx] : null),
};

async function api(path, body) {
  const init = { headers: { Authorization: "Bearer " + token }, cache: "no-store" };
  if (body !== undefined) {
    init.method = "POST";
    init.headers["Content-Type"] = "application/json";
    init.body = JSON.stringify(body);
  }
  const r = await fetch(path, init);
  const data = await r.json().catch(() => ({ result: "failed", message: "HTTP " + r.status }));
  if (!r.ok) throw new Error(data.message || "HTTP " + r.status);
  return data;
}

function fmt(v, n = 1) { return typeof v === "number" && isFinite(v) ? v.toFixed(n) : "–"; }

function selectedList() { return state.names.filter((n) => state.selected.has(n)); }

function showSelection() {
  const sel = selectedList();
  $("selection").textContent = sel.length ? sel.join(", ") : "none (commands go to the vehicles you select)";
  $("mission-for").textContent = "for " + (sel.length ? sel.join(", ") : "all vehicles");
  for (const b of document.querySelectorAll('button.cmd[data-to="selected"]')) {
    b.disabled = sel.length === 0;
    b.title = sel.length ? "" : "select a vehicle first (click it on the map or in the list)";
  }
  for (const tr of document.querySelectorAll("tr.vehicle")) tr.classList.toggle("selected", state.selected.has(tr.dataset.name));
  for (const cb of document.querySelectorAll("input.select")) cb.checked = state.selected.has(cb.dataset.name);
}

function toggle(name, add) {
  if (!add) {
    const only = state.selected.size === 1 && state.selected.has(name);
    state.selected.clear();
    if (!only) state.selected.add(name);
  } else if (state.selected.has(name)) state.selected.delete(name);
  else state.selected.add(name);
  showSelection();
  draw();
}

function buildRows() {
  const body = $("vehicles").querySelector("tbody");
  body.textContent = "";
  for (const n of state.names) {
    const tr = document.createElement("tr");
    tr.className = "vehicle";
    tr.dataset.name = n;
    tr.innerHTML = `<td><span class="swatch"></span><span class="name"></span></td><td><input type="checkbox" class="select"></td>` +
      `<td class="mode">–</td><td class="armed">–</td><td class="pos">–</td><td class="mission">–</td>`;
    tr.querySelector(".swatch").style.background = state.colours[n];
    tr.querySelector(".name").textContent = n;
    const cb = tr.querySelector("input.select");
    cb.dataset.name = n;
    cb.addEventListener("click", (e) => { e.stopPropagation(); toggle(n, true); });
    tr.addEventListener("click", (e) => toggle(n, e.shiftKey || e.ctrlKey || e.metaKey));
    body.appendChild(tr);
  }
  showSelection();
}

function updateRows() {
  for (const tr of document.querySelectorAll("tr.vehicle")) {
    const v = state.vehicles[tr.dataset.name] || {};
    tr.querySelector(".mode").textContent = v.mode || "–";
    tr.querySelector(".armed").textContent = v.armed === undefined ? "–" : v.armed ? "armed" : "disarmed";
    const p = v.p_W;
    tr.querySelector(".pos").textContent = p ? `${fmt(p[0])}, ${fmt(p[1])}, ${fmt(p[2])}` : "–";
    const m = v.mission;
    tr.querySelector(".mission").textContent = m && m.count ? `${Math.min(m.current, m.count)}/${m.count}` : "—";
  }
}

function logLine(text, bad) {
  const d = document.createElement("div");
  d.textContent = text;
  if (bad) d.className = "bad";
  $("events").prepend(d);
  while ($("events").childNodes.length > 200) $("events").lastChild.remove();
}

async function poll() {
  try {
    const s = await api("/api/state");
    $("conn").textContent = "connected";
    $("conn").className = "good";
    if (s.names.join() !== state.names.join()) {
      state.names = s.names;
      state.colours = s.colours;
      buildRows();
    }
    state.vehicles = s.vehicles;
    state.areas = s.areas || { fields: {}, geofence: null };
    $("scenario").textContent = s.scenario;
    $("t").textContent = fmt(s.t, 2);
    $("paused").textContent = s.ended ? `ended: ${s.ended}` : s.held ? "waiting for Start (the scenario's own mission)" : s.paused ? "paused" : "";
    $("start").disabled = !s.held;
    $("start").title = s.held ? "start the fleet's own mission" : "the fleet has started";
    for (const n of state.names) {
      const p = (s.vehicles[n] || {}).p_W;
      if (!p) continue;
      const tr = (state.trails[n] = state.trails[n] || []);
      const last = tr[tr.length - 1];
      if (!last || Math.hypot(p[0] - last[0], p[1] - last[1]) > 0.05) tr.push([p[0], p[1]]);
      if (tr.length > 3000) tr.shift();
    }
    for (const e of s.events) {
      if (e.seq <= state.events) continue;
      state.events = e.seq;
      logLine(`${fmt(e.t, 2)} ${e.vehicle} ${e.kind}: ${e.message}`, e.kind === "denied" || e.kind === "error");
    }
    updateRows();
    draw();
  } catch (err) {
    $("conn").textContent = "disconnected: " + err.message;
    $("conn").className = "bad";
  }
  setTimeout(poll, 200);
}

// ---- the map --------------------------------------------------------------------------------------------------
let view = null; // {sx, ox, oy}: canvas = ox + sx * x, oy - sx * y
function bounds() {
  const pts = [];
  for (const n of state.names) {
    const v = state.vehicles[n] || {};
    if (v.p_W) pts.push(v.p_W);
    if (v.home_p_W) pts.push(v.home_p_W);
    for (const p of state.trails[n] || []) pts.push(p);
  }
  if (state.preview) for (const wp of Object.values(state.preview.waypoints)) for (const p of wp) pts.push(p);
  for (const p of state.area) pts.push(p);
  for (const poly of Object.values((state.areas || {}).fields || {})) for (const p of poly) pts.push(p);
  if (!pts.length) return [-5, -5, 5, 5];
  let [x0, y0, x1, y1] = [Infinity, Infinity, -Infinity, -Infinity];
  for (const p of pts) { x0 = Math.min(x0, p[0]); x1 = Math.max(x1, p[0]); y0 = Math.min(y0, p[1]); y1 = Math.max(y1, p[1]); }
  const pad = Math.max(2, 0.1 * Math.max(x1 - x0, y1 - y0));
  return [x0 - pad, y0 - pad, x1 + pad, y1 + pad];
}

function draw() {
  const c = $("map");
  const w = c.clientWidth, h = c.clientHeight;
  if (c.width !== w || c.height !== h) { c.width = w; c.height = h; }
  const g = c.getContext("2d");
  g.clearRect(0, 0, w, h);
  if (!(view && $("draw-area").checked && view.w === w && view.h === h)) { // the map holds still while an area is drawn
    const [bx0, by0, bx1, by1] = bounds();
    const s = Math.min(w / (bx1 - bx0), h / (by1 - by0));
    view = { sx: s, ox: w / 2 - s * (bx0 + bx1) / 2, oy: h / 2 + s * (by0 + by1) / 2, w, h };
  }
  const { sx, ox, oy } = view;
  const x0 = -ox / sx, x1 = (w - ox) / sx, y0 = (oy - h) / sx, y1 = oy / sx; // what the canvas shows [m]
  const X = (x) => ox + sx * x, Y = (y) => oy - sx * y;
  // grid: 1, 2, 5, 10 ... m
  const step = [1, 2, 5, 10, 20, 50, 100].find((s) => s * sx >= 40) || 200;
  g.strokeStyle = "#e6e6e6"; g.lineWidth = 1; g.fillStyle = "#888"; g.font = "10px system-ui";
  for (let x = Math.ceil(x0 / step) * step; x <= x1; x += step) { g.beginPath(); g.moveTo(X(x), 0); g.lineTo(X(x), h); g.stroke(); g.fillText(`${x} m`, X(x) + 2, h - 4); }
  for (let y = Math.ceil(y0 / step) * step; y <= y1; y += step) { g.beginPath(); g.moveTo(0, Y(y)); g.lineTo(w, Y(y)); g.stroke(); g.fillText(`${y} m`, 2, Y(y) - 2); }
  // the scenario's named fields (green, named) and geofence (orange, dashed)
  const areas = state.areas || { fields: {}, geofence: null };
  const outline = (poly) => { g.beginPath(); poly.forEach((p, i) => (i ? g.lineTo(X(p[0]), Y(p[1])) : g.moveTo(X(p[0]), Y(p[1])))); g.closePath(); };
  if (areas.geofence) { g.strokeStyle = "#e67e00"; g.lineWidth = 1.5; g.setLineDash([8, 5]); outline(areas.geofence); g.stroke(); g.setLineDash([]); }
  for (const [name, poly] of Object.entries(areas.fields)) {
    g.strokeStyle = "#3a7d3a"; g.fillStyle = "rgba(58, 125, 58, 0.07)"; g.lineWidth = 1.5; outline(poly); g.fill(); g.stroke();
    g.fillStyle = "#3a7d3a"; g.font = "11px system-ui"; g.fillText(name, X(poly[0][0]) + 4, Y(poly[0][1]) - 4);
  }
  // the operator's area: a grey polygon, its corners marked
  if (state.area.length) {
    g.strokeStyle = "#444"; g.fillStyle = "rgba(0, 0, 0, 0.06)"; g.lineWidth = 1.5;
    g.beginPath();
    state.area.forEach((p, i) => (i ? g.lineTo(X(p[0]), Y(p[1])) : g.moveTo(X(p[0]), Y(p[1]))));
    if (state.area.length > 2) g.closePath();
    g.fill(); g.stroke();
    g.fillStyle = "#444";
    for (const p of state.area) g.fillRect(X(p[0]) - 3, Y(p[1]) - 3, 6, 6);
  }
  // the previewed mission: dashed, numbered, in each vehicle's colour
  if (state.preview) {
    for (const [n, wp] of Object.entries(state.preview.waypoints)) {
      g.strokeStyle = state.colours[n] || "#000"; g.fillStyle = g.strokeStyle; g.lineWidth = 2; g.setLineDash([6, 4]);
      g.beginPath();
      wp.forEach((p, i) => (i ? g.lineTo(X(p[0]), Y(p[1])) : g.moveTo(X(p[0]), Y(p[1]))));
      g.stroke(); g.setLineDash([]);
      wp.forEach((p, i) => { g.beginPath(); g.arc(X(p[0]), Y(p[1]), 3, 0, 2 * Math.PI); g.fill(); g.fillText(String(i + 1), X(p[0]) + 4, Y(p[1]) - 4); });
    }
  }
  for (const n of state.names) {
    const col = state.colours[n], v = state.vehicles[n] || {}, tr = state.trails[n] || [];
    g.strokeStyle = col; g.lineWidth = 1.5; g.globalAlpha = 0.6;
    g.beginPath(); tr.forEach((p, i) => (i ? g.lineTo(X(p[0]), Y(p[1])) : g.moveTo(X(p[0]), Y(p[1])))); g.stroke();
    g.globalAlpha = 1;
    if (v.home_p_W) { g.strokeStyle = col; g.strokeRect(X(v.home_p_W[0]) - 5, Y(v.home_p_W[1]) - 5, 10, 10); }
    if (!v.p_W) continue;
    const px = X(v.p_W[0]), py = Y(v.p_W[1]), yaw = v.rpy ? v.rpy[2] : 0;
    if (state.selected.has(n)) { g.strokeStyle = "#000"; g.lineWidth = 2; g.beginPath(); g.arc(px, py, 12, 0, 2 * Math.PI); g.stroke(); }
    g.fillStyle = col; g.beginPath(); g.arc(px, py, 7, 0, 2 * Math.PI); g.fill();
    g.strokeStyle = col; g.lineWidth = 2; g.beginPath(); g.moveTo(px, py); g.lineTo(px + 16 * Math.cos(yaw), py - 16 * Math.sin(yaw)); g.stroke();
    g.fillStyle = "#000"; g.font = "11px system-ui"; g.fillText(`${n} ${fmt(v.p_W[2])} m`, px + 10, py + 14);
  }
}

$("map").addEventListener("click", (e) => {
  if (!view) return;
  const r = $("map").getBoundingClientRect();
  const mx = e.clientX - r.left, my = e.clientY - r.top;
  if ($("draw-area").checked) { // a corner of the operator's area, in world coordinates [m]
    state.area.push([+((mx - view.ox) / view.sx).toFixed(2), +((view.oy - my) / view.sx).toFixed(2)]);
    showArea();
    setPreview(null);
    draw();
    return;
  }
  let best = null, bestD = 20;
  for (const n of state.names) {
    const p = (state.vehicles[n] || {}).p_W;
    if (!p) continue;
    const d = Math.hypot(view.ox + view.sx * p[0] - mx, view.oy - view.sx * p[1] - my);
    if (d < bestD) { best = n; bestD = d; }
  }
  if (best) toggle(best, e.shiftKey || e.ctrlKey || e.metaKey);
});
window.addEventListener("resize", draw);

// ---- commands -------------------------------------------------------------------------------------------------
async function command(cmd, to) {
  const vehicles = to === "all" ? "all" : selectedList();
  try {
    const r = await api("/api/command", { command: cmd, vehicles });
    for (const [n, a] of Object.entries(r.acks)) logLine(`${n} ${r.command}: ${a.result}${a.message ? " (" + a.message + ")" : ""}`, a.result !== "accepted" && a.result !== "in_progress");
  } catch (err) {
    logLine(`${cmd.command}: refused (${err.message})`, true);
  }
}
for (const b of document.querySelectorAll("button.cmd")) {
  b.addEventListener("click", () => {
    const cmd = { command: b.dataset.cmd };
    if (cmd.command === "takeoff") cmd.altitude = Number($("takeoff-alt").value);
    command(cmd, b.dataset.to);
  });
}
$("pause").addEventListener("click", () => command({ command: "sim_pause" }, "all"));
$("resume").addEventListener("click", () => command({ command: "sim_resume" }, "all"));
$("start").addEventListener("click", () => command({ command: "start" }, "all"));

// ---- the mission box: preview first, then Fly --------------------------------------------------------------------
function setPreview(p) {
  state.preview = p;
  $("fly").disabled = !p;
  $("fly").title = p ? `fly mission ${p.id} as shown on the map` : "preview a mission first: only what is shown on the map can be flown";
  draw();
}
$("mission-text").addEventListener("input", () => setPreview(null)); // a changed request must be previewed again
function showArea() {
  const n = state.area.length;
  $("area-info").textContent = n === 0 ? "" : n < 3 ? `${n} corner${n > 1 ? "s" : ""} (3 or more make an area)` : `area of ${n} corners`;
}
$("clear-area").addEventListener("click", () => { state.area = []; showArea(); setPreview(null); draw(); });
$("preview").addEventListener("click", async () => {
  const sel = selectedList();
  const res = $("mission-result");
  res.className = "";
  res.textContent = "reading the request…";
  try {
    const body = { text: $("mission-text").value, vehicles: sel.length ? sel : "all" };
    if (state.area.length >= 3) body.area = state.area;
    const r = await api("/api/mission/preview", body);
    if (r.ok) {
      res.className = "good";
      res.textContent = `preview ${r.id}: ${r.summary}. Check it on the map, then Fly.`;
      setPreview(r);
    } else {
      res.className = "bad";
      res.textContent = "refused: " + r.reason;
      setPreview(null);
    }
  } catch (err) {
    res.className = "bad";
    res.textContent = "refused: " + err.message;
    setPreview(null);
  }
});
$("fly").addEventListener("click", async () => {
  const p = state.preview;
  if (!p) return;
  const res = $("mission-result");
  try {
    const r = await api("/api/mission/fly", { id: p.id });
    res.className = r.ok ? "good" : "bad";
    res.textContent = r.ok ? `flying mission ${p.id}: ${p.summary}` : "refused: " + r.reason;
  } catch (err) {
    res.className = "bad";
    res.textContent = "refused: " + err.message;
  }
  $("fly").disabled = true; // flown (or refused): preview again for the next
});

poll();
