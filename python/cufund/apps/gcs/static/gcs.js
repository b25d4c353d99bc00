// cufund web ground station, the page's main thread: the websocket, the panel, the plots, the commands and the camera.
// The 3-D view is drawn by view.js in a Web Worker (see there why); this thread posts it only what it needs.
"use strict";
(function () {
  // URL parameters: token; fps (3-D redraw cap, 20); dpr (device-pixel-ratio cap, 1.5); aa (multisampling: 1, 0;
  // default off with a software WebGL renderer); view=page (draw the 3-D view in the page, not a worker)
  const query = new URLSearchParams(location.search);
  const token = query.get("token") || "";
  const $ = (id) => document.getElementById(id);
  const PLOT_S = 20;

  // ---- state shared with tests and benchmarks -------------------------------------------------------------------
  const stats = {telemetry: 0, clouds: 0, rateHz: 0, arrivals: [], lastTelemetry: null, acks: [], errors: [],
                 hellos: 0, events: []};
  const gcs = window.gcs = {stats: stats, send: null, lastClick: null, lastPlan: null};

  // ---- the 3-D view: a worker drawing on the canvas, or (no OffscreenCanvas) the same code in this page ----------
  const canvas = document.createElement("canvas");
  canvas.id = "view3d";
  $("meshcat-pane").appendChild(canvas);
  gcs.canvas = canvas;
  const replies = {};
  let nextQuery = 1;
  function fromView(m) {
    if (m.type === "stats") { stats.fps = m.fps; stats.lagMs = m.lagMs; stats.frames = m.frames; stats.antialias = m.antialias; return; }
    if (m.type === "marker") {  // the view drew a new setpoint: the clicked one?
      const c = gcs.lastClick;
      if (c && c.drawnAt === undefined && Math.hypot(m.sp[0] - c.p_W[0], m.sp[1] - c.p_W[1]) < 0.01) c.drawnAt = m.at - performance.timeOrigin;
      return;
    }
    const cb = replies[m.id];
    delete replies[m.id];
    if (cb) cb(m.value);
  }
  let toView;
  const antialias = query.has("aa") ? query.get("aa") !== "0" : null;  // default: not with software WebGL
  gcs.viewInWorker = query.get("view") !== "page" && Boolean(canvas.transferControlToOffscreen && window.Worker);
  if (gcs.viewInWorker) {
    const worker = new Worker("/static/view.js");
    const off = canvas.transferControlToOffscreen();
    worker.postMessage({type: "init", canvas: off, antialias: antialias}, [off]);
    worker.onmessage = (e) => fromView(e.data);
    worker.onerror = (e) => { stats.errors.push("3-D view: " + e.message); };
    toView = (m, transfer) => worker.postMessage(m, transfer || []);
  } else {
    const pending = [];
    toView = (m) => pending.push(m);
    const load = (src, then) => { const el = document.createElement("script"); el.src = src; el.onload = then; document.head.appendChild(el); };
    load("/meshcat/main.min.js", () => load("/static/view.js", () => {
      const handle = window.cufundView(MeshCat.THREE, canvas, (r) => setTimeout(() => fromView(r)), antialias);
      toView = (m) => handle(m);
      for (const m of pending.splice(0)) handle(m);
    }));
  }
  const ask = (m) => new Promise((resolve) => { const id = nextQuery++; replies[id] = resolve; toView({...m, id: id}); });
  gcs.layerPoints = (name) => ask({type: "points", layer: name});  // the points a line / cloud layer draws
  gcs.drawn = () => ask({type: "drawn"});  // resolves once a frame with everything posted so far is drawn
  toView({type: "fps", fps: parseFloat(query.get("fps")) || 20});
  function resize() {
    const r = canvas.getBoundingClientRect();
    cam.aspect = r.width / Math.max(1, r.height);
    toView({type: "size", w: Math.max(1, Math.round(r.width)), h: Math.max(1, Math.round(r.height)),
            dpr: Math.min(window.devicePixelRatio || 1, parseFloat(query.get("dpr")) || 1.5)});
  }
  function applyVisibility() {
    const layers = {};
    for (const el of document.querySelectorAll("[data-layer]")) layers[el.dataset.layer] = el.checked;
    toView({type: "visible", layers: layers});
  }

  // ---- the camera: orbit about a target (ENU, z up), moved by this page, drawn by the view ---------------------
  // p = target + radius (cos el cos az, cos el sin az, sin el); vertical field of view fov [deg], as three.js's
  // PerspectiveCamera looking at the target with up = z; the projection below is the same, done analytically.
  const cam = {target: [0, 0, 0], radius: 1, az: 0, el: 0, fov: 75, aspect: 1, near: 0.01, far: 100};
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const unit = (a) => { const n = Math.hypot(a[0], a[1], a[2]); return [a[0] / n, a[1] / n, a[2] / n]; };
  function setOffset(off) {  // the camera at target + off
    cam.radius = Math.hypot(off[0], off[1], off[2]);
    cam.az = Math.atan2(off[1], off[0]);
    cam.el = Math.asin(off[2] / cam.radius);
  }
  function camPosition() {
    const c = Math.cos(cam.el);
    return [cam.target[0] + cam.radius * c * Math.cos(cam.az), cam.target[1] + cam.radius * c * Math.sin(cam.az),
            cam.target[2] + cam.radius * Math.sin(cam.el)];
  }
  function camBasis() {  // position, forward, right, up
    const p = camPosition(), f = unit(sub(cam.target, p)), r = unit(cross(f, [0, 0, 1]));
    return {p: p, f: f, r: r, u: cross(r, f)};
  }
  function postCamera() { toView({type: "camera", p: camPosition(), target: cam.target, fov: cam.fov}); }
  function project(x) {  // a world point to the canvas (CSS pixels, page coordinates) and its depth in [-1, 1]
    const b = camBasis(), d = sub(x, b.p), zc = dot(d, b.f), t = Math.tan(cam.fov * Math.PI / 360);
    const nx = dot(d, b.r) / (zc * t * cam.aspect), ny = dot(d, b.u) / (zc * t), rect = canvas.getBoundingClientRect();
    const z = (cam.far + cam.near) / (cam.far - cam.near) - 2 * cam.far * cam.near / ((cam.far - cam.near) * zc);
    return {x: rect.left + (nx + 1) / 2 * rect.width, y: rect.top + (1 - ny) / 2 * rect.height, z: z};
  }
  gcs.screenOf = (p_W) => { const s = project(p_W); return {x: s.x, y: s.y}; };
  gcs.vehicleScreen = function () {  // the vehicle's pixel in the 3-D pane (CSS pixels, page coordinates)
    const t = stats.lastTelemetry;
    return t && Array.isArray(t.p_W) ? project(t.p_W) : null;
  };
  gcs.groundPoint = function (clientX, clientY) {  // the ENU point [x, y] on the ground (z = 0) under a pixel, or null
    const rect = canvas.getBoundingClientRect(), b = camBasis(), t = Math.tan(cam.fov * Math.PI / 360);
    const nx = ((clientX - rect.left) / rect.width) * 2 - 1, ny = 1 - ((clientY - rect.top) / rect.height) * 2;
    const dir = [0, 1, 2].map((k) => b.f[k] + nx * t * cam.aspect * b.r[k] + ny * t * b.u[k]);
    if (Math.abs(dir[2]) < 1e-9) return null;
    const s = -b.p[2] / dir[2];
    return s > 0 ? [b.p[0] + s * dir[0], b.p[1] + s * dir[1]] : null;
  };
  let following = false;
  function follow(p) {
    if (!$("follow").checked || !Array.isArray(p)) { following = false; return; }
    if (!following) setOffset([-2.5, -2.5, 1.8]);  // the first time 2.5 m behind and 1.8 m above; then the user's orbit
    following = true;
    cam.target = p.slice(0, 3);
    postCamera();
  }

  // ---- telemetry panel and plots -------------------------------------------------------------------------------
  const fmt = (v, n = 2) => (typeof v === "number" ? v.toFixed(n) : (v === undefined || v === null ? "–" : String(v)));
  const vec = (v, n = 2) => (Array.isArray(v) ? v.map((x) => fmt(x, n)).join(", ") : fmt(v, n));
  const pick = (t, ...keys) => { for (const k of keys) { const v = k.split(".").reduce((o, p) => (o == null ? undefined : o[p]), t); if (v !== undefined && v !== null) return v; } return undefined; };
  const norm = (v) => (Array.isArray(v) ? Math.hypot(...v) : v);
  const plot = {t: [], p: [], sp: [], track: [], odom: []};

  function showTelemetry(t) {
    const p = t.p_W;
    const waits = t.start && t.start.available && !t.start.started && t.paused;  // a run held for Start
    $("tel-t").textContent = fmt(t.t, 2) + (waits ? " (waits for Start)" : t.paused ? " (paused)" : "");
    $("tel-rate").textContent = stats.rateHz.toFixed(0) + " Hz";
    const commanded = gcs.capabilities.commander !== false;  // without a commander there is no arming nor mode
    $("tel-mode").textContent = commanded ? fmt(t.mode) : "its planner's (no commander)";
    $("tel-armed").textContent = commanded ? fmt(t.armed) : "—";
    $("tel-landed").textContent = commanded ? fmt(t.landed) : "—";
    $("tel-flight-mode").textContent = fmt(t.flight_mode);
    $("tel-controller").textContent = fmt(t.controller);
    $("tel-mission").textContent = missionText(t);
    if (Array.isArray(p)) { $("tel-xy").textContent = vec(p.slice(0, 2)); $("tel-alt").textContent = fmt(p[2], 2); }
    $("tel-v").textContent = vec(t.v_W);
    $("tel-speed").textContent = fmt(norm(t.v_W));
    const rpy = pick(t, "rpy", "rpy_deg");
    const deg = Array.isArray(rpy) ? rpy.map((x) => x * (t.rpy_deg ? 1 : 180 / Math.PI)) : null;
    $("tel-rpy").textContent = deg ? deg.map((x) => fmt(x, 1)).join(", ") + " °" : "–";
    drawInstruments(deg);
    const margin = pick(t, "thrust_margin");
    $("tel-thrust").textContent = typeof margin === "number" ? `${(100 * margin).toFixed(0)} %` : "–";
    const est = estimatorText(pick(t, "estimator_health", "estimator"));
    $("tel-est").textContent = est.text; $("tel-est").className = est.ok ? "ok" : "bad";
    $("tel-track").textContent = fmt(norm(pick(t, "tracking_error", "tracking_error_m")), 3);
    $("tel-odom").textContent = fmt(norm(pick(t, "odometry_error", "odometry_error_m")), 3);
    if ($("tel-raw").parentElement.open) $("tel-raw").textContent = JSON.stringify(t, null, 1);
  }
  // The mission field: "—" before a mission, "3/5 through" while one runs (a scenario's own mission: its progress
  // and state; a waypoint mission: the item flown, counted from 1).
  function missionText(t) {
    const ms = t.mission_state, m = t.mission;
    if (ms && (!m || !m.count || t.mode === "mission" && !(m.current >= 0))) {
      if (/waiting/.test(ms.reason || "")) return "— (waits for Start)";
      const count = typeof ms.count === "number" ? "/" + ms.count : "";
      return `${ms.progress}${count} ${ms.state}${ms.reason ? ": " + ms.reason : ""}`;
    }
    if (m && typeof m.count === "number" && m.count > 0) {
      return m.current >= 0 ? `${m.current + 1}/${m.count}` : `—/${m.count} (uploaded)`;
    }
    return "—";
  }
  // The estimator's health in words: ok and how old its newest estimate is, or what is wrong.
  function estimatorText(e) {
    if (e === undefined || e === null) return {text: "–", ok: true};
    if (typeof e !== "object") return {text: String(e), ok: Boolean(e)};
    const age = typeof e.age_s === "number" ? (e.age_s < 1 ? `${Math.round(1000 * e.age_s)} ms old` : `${e.age_s.toFixed(1)} s old`) : "";
    if (e.source) return {text: `ok (${e.source})`, ok: e.ok !== false};
    const l = e.lidar || e.vision;  // a LiDAR (or visual-inertial) odometry's diagnostics of its newest frame
    const lidar = !l ? "" : e.vision ? (l.skipped ? `; camera frame skipped: ${l.skipped}` : `; ${l.inliers}/${l.tracked} features tracked`)
      : l.skipped ? `; LiDAR frame skipped: ${l.skipped}` : `; LiDAR ${l.inliers}/${l.points} points matched`;
    if (e.ok && (!l || l.healthy)) return {text: "ok" + (age ? `, estimate ${age}` : "") + lidar, ok: true};
    const why = l && !l.healthy ? (l.reason || "the odometry says unhealthy") : (age ? `estimate ${age}` : "no estimate yet");
    return {text: "NOT OK: " + why, ok: false};
  }
  // The attitude indicator (the horizon as seen from the vehicle: roll turns it, pitch moves it) and the heading
  // (compass degrees from north, clockwise: ENU yaw 0 is east, 090°).
  function drawInstruments(deg) {
    const a = $("attitude"), h = $("heading");
    const A = a.getContext("2d"), H = h.getContext("2d"), W = a.width, R = W / 2;
    A.save(); A.clearRect(0, 0, W, W);
    A.beginPath(); A.arc(R, R, R - 1, 0, 2 * Math.PI); A.clip();
    if (deg) {
      const roll = deg[0] * Math.PI / 180, pitch = deg[1], ppd = R / 45;  // 45 degrees of pitch to the rim
      A.translate(R, R); A.rotate(-roll); A.translate(0, pitch * ppd);
      A.fillStyle = "#6fa8dc"; A.fillRect(-2 * W, -2 * W, 4 * W, 2 * W);
      A.fillStyle = "#a0703c"; A.fillRect(-2 * W, 0, 4 * W, 2 * W);
      A.strokeStyle = "#fff"; A.lineWidth = 1; A.beginPath(); A.moveTo(-W, 0); A.lineTo(W, 0);
      for (const k of [-20, -10, 10, 20]) { A.moveTo(-12, -k * ppd); A.lineTo(12, -k * ppd); }
      A.stroke();
    } else { A.fillStyle = "#ddd"; A.fillRect(0, 0, W, W); }
    A.restore();
    A.strokeStyle = "#111"; A.lineWidth = 3; A.beginPath();
    A.moveTo(R - 34, R); A.lineTo(R - 10, R); A.lineTo(R, R + 8); A.lineTo(R + 10, R); A.lineTo(R + 34, R); A.stroke();
    A.lineWidth = 1; A.beginPath(); A.arc(R, R, R - 1, 0, 2 * Math.PI); A.stroke();
    H.clearRect(0, 0, W, W);
    H.strokeStyle = "#111"; H.lineWidth = 1; H.beginPath(); H.arc(R, R, R - 2, 0, 2 * Math.PI); H.stroke();
    H.fillStyle = "#333"; H.font = "bold 12px sans-serif"; H.textAlign = "center"; H.textBaseline = "middle";
    [["N", 0], ["E", 90], ["S", 180], ["W", 270]].forEach(([c, b]) => {
      const r = R - 12, x = R + r * Math.sin(b * Math.PI / 180), y = R - r * Math.cos(b * Math.PI / 180);
      H.fillText(c, x, y);
    });
    if (deg) {
      const hdg = ((90 - deg[2]) % 360 + 360) % 360, b = hdg * Math.PI / 180;
      H.strokeStyle = "#c62828"; H.lineWidth = 3; H.beginPath();
      H.moveTo(R - 14 * Math.sin(b), R + 14 * Math.cos(b)); H.lineTo(R + (R - 26) * Math.sin(b), R - (R - 26) * Math.cos(b)); H.stroke();
      $("att-text").textContent = `roll ${deg[0].toFixed(1)}°, pitch ${deg[1].toFixed(1)}°`;
      $("hdg-text").textContent = `heading ${String(Math.round(hdg) % 360).padStart(3, "0")}° (yaw ${deg[2].toFixed(1)}°)`;
    }
  }
  function setpointOf(t) { const s = pick(t, "setpoint_p_W", "setpoint.p_W", "setpoint"); return Array.isArray(s) ? s : null; }
  function targetOf(t) { const s = pick(t, "target_p_W", "status.target_p_W"); return Array.isArray(s) ? s : null; }

  function addPlot(t) {
    if (typeof t.t !== "number" || !Array.isArray(t.p_W)) return;
    if (plot.t.length && t.t < plot.t[plot.t.length - 1]) for (const k in plot) plot[k].length = 0;  // a restart
    plot.t.push(t.t); plot.p.push(t.p_W); plot.sp.push(setpointOf(t));
    plot.track.push(norm(pick(t, "tracking_error", "tracking_error_m")) ?? null);
    plot.odom.push(norm(pick(t, "odometry_error", "odometry_error_m")) ?? null);
    while (plot.t.length && plot.t[0] < t.t - PLOT_S) for (const k in plot) plot[k].shift();
  }
  function niceStep(span, n) {  // a 1-2-5 tick step giving about n ticks over span
    const raw = span / Math.max(1, n), p = Math.pow(10, Math.floor(Math.log10(raw))), f = raw / p;
    return (f < 1.5 ? 1 : f < 3.5 ? 2 : f < 7.5 ? 5 : 10) * p;
  }
  // A plot of the last PLOT_S seconds: value ticks on the left, simulated-time ticks below (the axis titles and
  // the legend are the figure's DOM around the canvas).
  function drawPlot(id, series, colors, dashed, minSpan) {
    const c = $(id);
    const cw = Math.round(c.clientWidth);
    if (cw > 0 && c.width !== cw) c.width = cw;
    const ctx = c.getContext("2d"), W = c.width, H = c.height, L = 36, B = 14, T = 4, Rm = 6;
    ctx.clearRect(0, 0, W, H);
    const tEnd = plot.t.length ? plot.t[plot.t.length - 1] : 0, t0 = Math.max(0, tEnd - PLOT_S), t1 = t0 + PLOT_S;
    let lo = Infinity, hi = -Infinity;
    for (const s of series) for (const v of s) if (v !== null && isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
    if (!isFinite(lo)) { lo = 0; hi = minSpan; }
    if (hi - lo < minSpan) { const m = (hi + lo) / 2; lo = m - minSpan / 2; hi = m + minSpan / 2; }
    const x = (t) => L + ((t - t0) / (t1 - t0)) * (W - L - Rm), y = (v) => T + (1 - (v - lo) / (hi - lo)) * (H - T - B);
    ctx.font = "10px sans-serif"; ctx.strokeStyle = "#e4e4e4"; ctx.fillStyle = "#555"; ctx.lineWidth = 1;
    const vs = niceStep(hi - lo, 4), digits = Math.max(0, -Math.floor(Math.log10(vs) + 1e-9));
    ctx.textAlign = "right"; ctx.textBaseline = "middle";
    for (let v = Math.ceil(lo / vs) * vs; v <= hi + 1e-9; v += vs) {
      ctx.beginPath(); ctx.moveTo(L, y(v)); ctx.lineTo(W - Rm, y(v)); ctx.stroke();
      ctx.fillText(v.toFixed(digits), L - 3, y(v));
    }
    ctx.textAlign = "center"; ctx.textBaseline = "top";
    for (let s = Math.ceil(t0 / 5) * 5; s <= t1 + 1e-9; s += 5) {
      ctx.beginPath(); ctx.moveTo(x(s), T); ctx.lineTo(x(s), H - B); ctx.stroke();
      ctx.fillText(String(s), x(s), H - B + 2);
    }
    ctx.strokeStyle = "#999"; ctx.strokeRect(L, T, W - L - Rm, H - T - B);
    if (plot.t.length < 2) return;
    ctx.lineWidth = 1.5;
    series.forEach((s, k) => {
      ctx.strokeStyle = colors[k]; ctx.setLineDash(dashed[k] ? [4, 3] : []); ctx.beginPath();
      let pen = false;
      for (let i = 0; i < s.length; i++) {
        if (s[i] === null || !isFinite(s[i])) { pen = false; continue; }
        if (pen) ctx.lineTo(x(plot.t[i]), y(s[i])); else ctx.moveTo(x(plot.t[i]), y(s[i]));
        pen = true;
      }
      ctx.stroke();
    });
    ctx.setLineDash([]);
  }
  function drawPlots() {
    const axis = (arr, k) => arr.map((p) => (p ? p[k] : null));
    drawPlot("plot-pos", [0, 1, 2, 0, 1, 2].map((k, i) => axis(i < 3 ? plot.p : plot.sp, k)),
             ["#d62728", "#2ca02c", "#1f77b4", "#d62728", "#2ca02c", "#1f77b4"], [0, 0, 0, 1, 1, 1], 0.5);
    drawPlot("plot-err", [plot.track, plot.odom], ["#9467bd", "#8c564b"], [0, 0], 0.05);
  }
  setInterval(drawPlots, 200);

  // Telemetry comes at up to 50 Hz; the panel is laid out 10 times a second (the target at once: see onText).
  let dirtyPanel = false;
  setInterval(() => { if (dirtyPanel && stats.lastTelemetry) { dirtyPanel = false; showTelemetry(stats.lastTelemetry); } }, 100);

  function newScene(sc) {
    $("scenario").textContent = sc.scenario ? "— " + sc.scenario : "";
    toView({type: "scene", meshes: sc.meshes || [], arm_length: sc.arm_length || 0.15});
    showGates(sc.gates || []);
    cam.target = [0, 0, 0];
    setOffset([-4, -4, 3]);  // 4 m behind and 3 m above the origin
    following = false;
    postCamera();
    applyVisibility();
  }
  function showGates(gates) {  // the gates the vehicle detected (its estimated frame): drawn, and named for LTLf
    toView({type: "gates", gates: gates});
    $("gates").textContent = gates.length ? gates.map((g) => `${g.name} ${vec(g.centre_W)} (${Math.round(100 * g.confidence)} %)`).join("\n") : "none detected";
  }
  let shownTarget = "";
  function showTarget(t) {  // the commander's target, written as soon as it changes
    const tg = targetOf(t) || setpointOf(t), text = tg ? vec(tg) : "–";
    if (text !== shownTarget) { shownTarget = text; $("tel-target").textContent = text; }
    return tg;
  }
  function toViewPose(t, sp) {  // sp: the target showTarget returned for t
    toView({type: "pose", p: t.p_W, q: t.q_WB, sp: sp});
    follow(t.p_W);
  }

  // ---- event log ------------------------------------------------------------------------------------------------
  // One line an event: its time and its message, the kind said once ("mode takeoff", not "mode mode takeoff";
  // "armed", not "armed armed"): the kind is shown only when its words are not already in the message. A failsafe
  // (issue 30: kind "failsafe") reads "FAILSAFE <what it did and why>".
  function eventText(e) {
    const kind = String(e.kind || e.type || e.level || "");
    let msg = e.message !== undefined && e.message !== null ? String(e.message) : JSON.stringify(e);
    let label = kind;
    if (/^failsafe$/i.test(kind)) {
      label = "FAILSAFE";
      msg = msg.replace(/^\s*failsafe\b[:\s-]*/i, "");
      const extra = ["action", "reason"].filter((k) => typeof e[k] === "string" && e[k] && !msg.includes(e[k])).map((k) => e[k]);
      if (extra.length) msg += (msg ? " — " : "") + extra.join(": ");
    } else {
      const words = kind.toLowerCase().split(/[_\s]+/).filter((w) => w);
      const said = msg.toLowerCase().split(/[^a-z0-9]+/);
      if (!words.length || words.every((w) => said.includes(w))) label = "";
    }
    const t = typeof e.t === "number" ? e.t.toFixed(2) + " s" : "–";
    return {text: `${t}  ${label ? label + " " : ""}${msg}`, kind: kind};
  }
  gcs.eventText = eventText;
  function addEvents(list) {
    const box = $("events");
    for (const e of list) {
      stats.events.push(e);
      const div = document.createElement("div");
      const ev = eventText(e), kind = ev.kind;
      div.className = /^failsafe$/i.test(kind) ? "failsafe" : /warn|refus|denied/i.test(kind + e.message) ? "warn" : (/crash|error|fail/i.test(kind + e.message) ? "error" : "");
      div.textContent = ev.text;
      box.appendChild(div);
    }
    while (box.childNodes.length > 500) box.removeChild(box.firstChild);
    box.scrollTop = box.scrollHeight;
  }

  // ---- websocket -----------------------------------------------------------------------------------------------
  let ws = null, nextId = 1, backoff = 250;
  const got = {telemetry: 0, cloud: 0};  // this connection's: the server sends more only as these are acknowledged
  function seen(stream) {
    got[stream] += 1;
    if (ws && ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify({type: "seen", telemetry: got.telemetry, cloud: got.cloud}));
  }
  const waiting = {};
  const rateWindow = [];
  function connect() {
    const url = (location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws?token=" + encodeURIComponent(token);
    ws = new WebSocket(url);
    ws.binaryType = "arraybuffer";
    ws.onopen = () => { $("conn").textContent = "connected"; $("conn").className = "good"; backoff = 250;
                        got.telemetry = got.cloud = 0;
                        ws.send(JSON.stringify({type: "seen", telemetry: 0, cloud: 0}));
                        ws.send(JSON.stringify({type: "layers", cloud: $("layer-cloud").checked})); };
    ws.onclose = () => { $("conn").textContent = "disconnected — reconnecting"; $("conn").className = "bad";
                         setTimeout(connect, backoff); backoff = Math.min(3000, backoff * 2); };
    ws.onmessage = (ev) => (typeof ev.data === "string" ? onText(JSON.parse(ev.data)) : onCloud(ev.data));
  }
  function onCloud(buf) {  // handed to the view as it is (transferred, not copied)
    stats.clouds += 1;
    seen("cloud");
    toView({type: "cloud", buf: buf}, [buf]);
  }
  function onText(m) {
    if (m.type === "telemetry") {
      const now = performance.now();
      stats.telemetry += 1; stats.lastTelemetry = m;
      rateWindow.push(now);
      while (rateWindow.length && rateWindow[0] < now - 2000) rateWindow.shift();
      stats.rateHz = rateWindow.length > 1 ? (rateWindow.length - 1) / ((now - rateWindow[0]) / 1000) : 0;
      const tg = showTarget(m);
      const c = gcs.lastClick;
      if (c && c.seenAt === undefined && tg && Math.hypot(tg[0] - c.p_W[0], tg[1] - c.p_W[1]) < 0.01) {
        c.seenAt = performance.now();  // the panel shows the clicked point as the target
        stats.arrivals.push(c.seenAt - c.t0);
        requestAnimationFrame(() => { c.paintedAt = performance.now(); });  // and the frame that paints it
      }
      seen("telemetry");
      if (m.start) showStart(m.start);
      addPlot(m); dirtyPanel = true;
      toViewPose(m, tg);
    } else if (m.type === "hello") {
      stats.hellos += 1;
      applyCapabilities(m.capabilities || {});
      newScene(m.scene);
      toView({type: "path", points: m.path || []});
      toView({type: "planned", points: m.planned || []});
      for (const k in plot) plot[k].length = 0;
      for (const t of m.history || []) addPlot(t);
      $("events").innerHTML = ""; stats.events = [];
      addEvents(m.events || []);
      toView({type: "esdf", esdf: m.esdf || null});  // the scene above dropped the old cloud and map
      if (m.telemetry && m.telemetry.start) showStart(m.telemetry.start);
      if (m.telemetry && m.telemetry.p_W) { stats.lastTelemetry = m.telemetry; showTelemetry(m.telemetry); toViewPose(m.telemetry, showTarget(m.telemetry)); }
    } else if (m.type === "events") {
      addEvents(m.events);
    } else if (m.type === "planned") {
      toView({type: "planned", points: m.planned});
    } else if (m.type === "esdf") {
      toView({type: "esdf", esdf: m});
    } else if (m.type === "gates") {
      showGates(m.gates);
    } else if (m.type === "ack") {
      stats.acks.push(m);
      const el = $("ack");
      el.textContent = `${m.command}: ${m.result}${m.message ? " — " + m.message : ""}`;
      el.className = m.result;
      const cb = waiting[m.id];
      delete waiting[m.id];
      if (cb) cb(m);
    } else if (m.type === "pong") {
      const cb = waiting[m.id];
      delete waiting[m.id];
      if (cb) cb(m);
    } else if (m.type === "error") {
      stats.errors.push(m.message);
      $("ack").textContent = "error: " + m.message; $("ack").className = "failed";
    }
  }
  gcs.send = function (command, cb) {
    if (!ws || ws.readyState !== WebSocket.OPEN) { $("ack").textContent = "not connected"; return null; }
    const id = nextId++;
    if (cb) waiting[id] = cb;
    ws.send(JSON.stringify({type: "command", id: id, command: command}));
    return id;
  };
  gcs.raw = (text) => ws.send(text);
  gcs.ping = () => new Promise((resolve) => {  // round trip page -> server -> page [ms]
    const id = nextId++;
    waiting[id] = () => resolve(performance.now() - t0);
    const t0 = performance.now();
    ws.send(JSON.stringify({type: "ping", id: id}));
  });
  gcs.dropConnection = () => ws.close();  // as a network drop would (tests: the page reconnects)

  // ---- what the scenario supports: the controls it cannot serve are disabled, the reason on hover ----------------
  const CONTROLS = {
    arm: ["cmd-arm"], disarm: ["cmd-disarm"], takeoff: ["cmd-takeoff", "takeoff-alt"], land: ["cmd-land"],
    rtl: ["cmd-rtl"], hold: ["cmd-hold"], goto: ["cmd-goto", "goto-x", "goto-y", "goto-z", "click-goto"],
    flight_mode: ["cmd-flight-mode", "flight-mode"], controller: ["cmd-controller", "controller"],
    mission_upload: ["cmd-upload", "waypoints"], mission_start: ["cmd-mission-start", "cmd-ltl-fly"],
    mission_clear: ["cmd-mission-clear"],
  };
  const titles = {};  // each control's own title, restored when it is enabled again
  gcs.capabilities = {};
  function setEnabled(id, why) {
    const el = $(id);
    if (!el) return;
    if (!(id in titles)) titles[id] = el.getAttribute("title") || "";
    el.disabled = Boolean(why);
    el.title = why || titles[id];
    const label = el.closest("label");
    if (label) { label.title = el.title; label.classList.toggle("disabled", Boolean(why)); }
  }
  function applyCapabilities(caps) {
    gcs.capabilities = caps;
    const off = caps.disabled || {};
    for (const [command, ids] of Object.entries(CONTROLS)) for (const id of ids) setEnabled(id, off[command] || "");
    if (!off.mission_start && !gcs.lastPlan) setEnabled("cmd-ltl-fly", "preview a plan first");
    if (Array.isArray(caps.controllers) && caps.controllers.length) {
      const sel = $("controller");
      sel.innerHTML = "";
      for (const k of caps.controllers) { const o = document.createElement("option"); o.textContent = k; sel.appendChild(o); }
    }
  }
  function showStart(st) {  // the Start button: enabled when the server can start the mission now, else why not
    setEnabled("cmd-start", st.available ? "" : (st.why || "not available"));
    if (st.available) $("cmd-start").title = "start the scenario's mission";
    $("start-state").textContent = st.available ? "waiting for Start" : (st.why || "");
  }

  // ---- controls -------------------------------------------------------------------------------------------------
  const num = (id) => parseFloat($(id).value);
  on("cmd-start", () => gcs.send({command: "start"}));
  function on(id, f) { $(id).addEventListener("click", f); }
  on("cmd-arm", () => gcs.send({command: "arm"}));
  on("cmd-disarm", () => gcs.send({command: "disarm"}));
  on("cmd-takeoff", () => gcs.send({command: "takeoff", altitude: num("takeoff-alt")}));
  on("cmd-land", () => gcs.send({command: "land"}));
  on("cmd-rtl", () => gcs.send({command: "rtl"}));
  on("cmd-hold", () => gcs.send({command: "hold"}));
  on("cmd-goto", () => gcs.send({command: "goto", p_W: [num("goto-x"), num("goto-y"), num("goto-z")]}));
  on("cmd-flight-mode", () => gcs.send({command: "flight_mode", mode: $("flight-mode").value}));
  on("cmd-controller", () => gcs.send({command: "controller", kind: $("controller").value}));
  on("cmd-pause", () => gcs.send({command: "sim_pause"}));
  on("cmd-resume", () => gcs.send({command: "sim_resume"}));
  on("cmd-speed", () => gcs.send({command: "sim_speed", speed: $("speed").value}));
  on("cmd-tunnel", () => gcs.send({command: "tunnel_start"}));
  function waypoints() {
    return $("waypoints").value.split("\n").map((l) => l.trim()).filter((l) => l).map((l) => l.split(/[\s,]+/).map(Number));
  }
  on("cmd-upload", () => gcs.send({command: "mission_upload", items: waypoints()}));
  on("cmd-mission-start", () => gcs.send({command: "mission_start"}));
  on("cmd-mission-clear", () => gcs.send({command: "mission_clear"}));
  on("cmd-ltl-preview", () => {
    let regions;
    try { regions = JSON.parse($("ltl-regions").value || "[]"); } catch (e) { $("ack").textContent = "regions: " + e.message; return; }
    gcs.send({command: "mission_preview", formula: $("ltl-formula").value, regions: regions}, (ack) => {
      gcs.lastPlan = ack.data || null;
      const off = (gcs.capabilities.disabled || {}).mission_start;
      setEnabled("cmd-ltl-fly", off || (ack.data ? "" : "preview a plan first"));
      $("ltl-plan").textContent = ack.data ? `${ack.data.regions.join(" → ")} (${ack.data.length.toFixed(2)} m)` : ack.message;
    });
  });
  on("cmd-ltl-fly", () => {
    if (!gcs.lastPlan) return;
    gcs.send({command: "mission_upload", items: gcs.lastPlan.waypoints_W}, (ack) => {
      if (ack.result === "accepted") gcs.send({command: "mission_start"});
    });
  });
  for (const el of document.querySelectorAll("[data-layer]")) el.addEventListener("change", () => {
    applyVisibility();
    if (el.id === "layer-cloud" && ws && ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify({type: "layers", cloud: el.checked}));
  });
  // ---- the pointer on the 3-D view: drag to orbit (left) or pan (right, or shift), wheel to zoom, click to go ----
  let drag = null;
  canvas.addEventListener("contextmenu", (e) => e.preventDefault());
  canvas.addEventListener("pointerdown", (e) => {
    drag = {x0: e.clientX, y0: e.clientY, x: e.clientX, y: e.clientY, pan: e.button !== 0 || e.shiftKey, moved: false};
    canvas.setPointerCapture(e.pointerId);
  });
  canvas.addEventListener("pointermove", (e) => {
    if (!drag) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y, h = canvas.clientHeight || 1;
    drag.x = e.clientX; drag.y = e.clientY;
    if (Math.hypot(e.clientX - drag.x0, e.clientY - drag.y0) > 4) drag.moved = true;
    if (!drag.moved) return;
    if (drag.pan) {  // the target moves with the pointer in the view plane
      const b = camBasis(), s = 2 * cam.radius * Math.tan(cam.fov * Math.PI / 360) / h;
      cam.target = [0, 1, 2].map((k) => cam.target[k] - s * (dx * b.r[k] - dy * b.u[k]));
    } else {
      cam.az -= 2 * Math.PI * dx / h;
      cam.el = Math.max(-1.5, Math.min(1.5, cam.el + Math.PI * dy / h));
    }
    postCamera();
  });
  canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    cam.radius = Math.max(0.2, Math.min(80, cam.radius * Math.pow(0.95, -e.deltaY / 100)));
    postCamera();
  }, {passive: false});
  canvas.addEventListener("pointerup", (e) => {
    const d = drag;
    drag = null;
    if (!d || d.moved || d.pan || !$("click-goto").checked) return;
    // a click: the ground point under it, intersected analytically (no scene ray cast), sent at once; the latency
    // is counted from the release's own time stamp, so that a busy page's delay in handling it is included
    const g = gcs.groundPoint(e.clientX, e.clientY);
    if (!g) return;
    const p = [Math.round(g[0] * 100) / 100, Math.round(g[1] * 100) / 100, num("goto-z")];
    const click = gcs.lastClick = {t0: e.timeStamp, handledAt: performance.now(), p_W: p};
    gcs.send({command: "goto", p_W: p}, () => { click.ackAt = performance.now(); });
    click.sentAt = performance.now();
  });
  new ResizeObserver(resize).observe(canvas);
  resize();
  postCamera();
  applyVisibility();
  connect();
})();
