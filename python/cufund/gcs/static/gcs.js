// cufund web ground station: MeshCat's viewer (three.js) for the 3-D view, one websocket for everything live.
"use strict";
(function () {
  const THREE = MeshCat.THREE;
  const token = new URLSearchParams(location.search).get("token") || "";
  const $ = (id) => document.getElementById(id);
  const viewer = new MeshCat.Viewer($("meshcat-pane"));
  viewer.renderer.shadowMap.enabled = false;  // no shadow-casting lights here; saves a pass per frame
  const scene = viewer.scene;  // MeshCat turns its scene so that paths under it are z-up (ENU)
  const MAX_PATH = 20000, MAX_CLOUD = 8000, PLOT_S = 20;

  // ---- 3-D layers ---------------------------------------------------------------------------------------------
  const root = ["cufund"];
  const layer = {};
  function addLayer(name, object) {
    viewer.set_object(root.concat([name]), object);
    layer[name] = viewer.scene_tree.find(root.concat([name, "<object>"])).object;
    return layer[name];
  }
  function lineObject(color, capacity) {
    const g = new THREE.BufferGeometry();
    g.setAttribute("position", new THREE.BufferAttribute(new Float32Array(3 * capacity), 3));
    g.setDrawRange(0, 0);
    const line = new THREE.Line(g, new THREE.LineBasicMaterial({color: color}));
    line.frustumCulled = false;
    return line;
  }
  function setLine(obj, points) {
    const attr = obj.geometry.attributes.position;
    const n = Math.min(points.length, attr.count);
    for (let i = 0; i < n; i++) attr.setXYZ(i, points[i][0], points[i][1], points[i][2]);
    attr.needsUpdate = true;
    obj.geometry.setDrawRange(0, n);
  }
  function appendLine(obj, p) {
    const attr = obj.geometry.attributes.position;
    let n = obj.geometry.drawRange.count;
    if (n >= attr.count) { attr.array.copyWithin(0, 3 * (attr.count >> 1)); n = attr.count - (attr.count >> 1); }
    attr.setXYZ(n, p[0], p[1], p[2]);
    attr.needsUpdate = true;
    obj.geometry.setDrawRange(0, n + 1);
  }
  function vehicleObject(d) {
    const g = new THREE.Group();
    const mat = (c) => new THREE.MeshLambertMaterial({color: c});
    const body = new THREE.Mesh(new THREE.BoxGeometry(0.8 * d, 0.8 * d, 0.35 * d), mat(0xd62728));
    g.add(body);
    const nose = new THREE.Mesh(new THREE.BoxGeometry(0.5 * d, 0.15 * d, 0.15 * d), mat(0xffd700));
    nose.position.set(0.6 * d, 0, 0);
    g.add(nose);
    for (let k = 0; k < 4; k++) {
      const a = Math.PI / 4 + k * Math.PI / 2;
      const arm = new THREE.Mesh(new THREE.BoxGeometry(2 * d, 0.1 * d, 0.08 * d), mat(0x202020));
      arm.rotation.z = a;
      g.add(arm);
      const rotor = new THREE.Mesh(new THREE.CylinderGeometry(0.45 * d, 0.45 * d, 0.03 * d, 24),
                                   mat(k % 2 ? 0xff7f0e : 0x1f77b4));
      rotor.rotation.x = Math.PI / 2;
      rotor.position.set(d * Math.cos(a), d * Math.sin(a), 0.08 * d);
      g.add(rotor);
    }
    return g;
  }
  function worldObject(meshes) {
    const g = new THREE.Group();
    for (const m of meshes) {
      const geom = new THREE.BufferGeometry();
      geom.setAttribute("position", new THREE.BufferAttribute(new Float32Array(m.vertices), 3));
      geom.setIndex(m.triangles);
      geom.computeVertexNormals();
      const see_through = m.label === "wall" || m.label === "ceiling";
      const c = new THREE.Color(m.color[0], m.color[1], m.color[2]);
      g.add(new THREE.Mesh(geom, new THREE.MeshLambertMaterial({
        color: c, side: THREE.DoubleSide, transparent: see_through, opacity: m.label === "ceiling" ? 0.08 : (see_through ? 0.25 : 1),
        depthWrite: !see_through})));
    }
    return g;
  }
  const esdfCanvas = document.createElement("canvas");
  function esdfObject(e) {
    const n = e.n, d = new Float32Array(Uint8Array.from(atob(e.d), (c) => c.charCodeAt(0)).buffer);
    esdfCanvas.width = n; esdfCanvas.height = n;
    const ctx = esdfCanvas.getContext("2d"), img = ctx.createImageData(n, n);
    for (let j = 0; j < n; j++) for (let i = 0; i < n; i++) {
      const v = d[j * n + i], k = 4 * ((n - 1 - j) * n + i);  // canvas rows run down, y runs up
      const s = Math.max(0, Math.min(1, v / 2));
      img.data[k] = v <= 0 ? 200 : 255 * (1 - s); img.data[k + 1] = v <= 0 ? 0 : 255 * s; img.data[k + 2] = 80; img.data[k + 3] = 255;
    }
    ctx.putImageData(img, 0, 0);
    const tex = new THREE.CanvasTexture(esdfCanvas);
    tex.magFilter = THREE.NearestFilter;
    const w = e.x[1] - e.x[0], h = e.y[1] - e.y[0];
    const mesh = new THREE.Mesh(new THREE.PlaneGeometry(w, h),
      new THREE.MeshBasicMaterial({map: tex, transparent: true, opacity: 0.45, side: THREE.DoubleSide, depthWrite: false}));
    mesh.position.set(e.x[0] + w / 2, e.y[0] + h / 2, e.z);
    return mesh;
  }

  const flown = addLayer("flown", lineObject(0xd62728, MAX_PATH));
  const planned = addLayer("planned", lineObject(0x1f77b4, 256));
  const cloudGeom = new THREE.BufferGeometry();
  cloudGeom.setAttribute("position", new THREE.BufferAttribute(new Float32Array(3 * MAX_CLOUD), 3));
  cloudGeom.setDrawRange(0, 0);
  const cloud = addLayer("cloud", new THREE.Points(cloudGeom, new THREE.PointsMaterial({color: 0xff8c00, size: 0.04})));
  cloud.frustumCulled = false;
  const setpoint = new THREE.Mesh(new THREE.SphereGeometry(0.04, 12, 8), new THREE.MeshLambertMaterial({color: 0x2ca02c}));
  let vehicle = null;
  const hidden = {};

  function applyVisibility() {
    for (const el of document.querySelectorAll("[data-layer]")) {
      const obj = layer[el.dataset.layer];
      if (obj) obj.visible = el.checked;
    }
    viewer.set_dirty();
  }

  // ---- state shared with tests and benchmarks -------------------------------------------------------------------
  const stats = {telemetry: 0, clouds: 0, rateHz: 0, arrivals: [], lastTelemetry: null, acks: [], errors: [],
                 hellos: 0, events: []};
  const gcs = window.gcs = {stats: stats, viewer: viewer, send: null, lastClick: null, lastPlan: null};

  // ---- telemetry panel and plots -------------------------------------------------------------------------------
  const fmt = (v, n = 2) => (typeof v === "number" ? v.toFixed(n) : (v === undefined || v === null ? "–" : String(v)));
  const vec = (v, n = 2) => (Array.isArray(v) ? v.map((x) => fmt(x, n)).join(", ") : fmt(v, n));
  const pick = (t, ...keys) => { for (const k of keys) { const v = k.split(".").reduce((o, p) => (o == null ? undefined : o[p]), t); if (v !== undefined && v !== null) return v; } return undefined; };
  const norm = (v) => (Array.isArray(v) ? Math.hypot(...v) : v);
  const plot = {t: [], p: [], sp: [], track: [], odom: []};

  function showTelemetry(t) {
    const p = t.p_W;
    $("tel-t").textContent = fmt(t.t, 2) + (t.paused ? " (paused)" : "");
    $("tel-mode").textContent = fmt(t.mode);
    $("tel-armed").textContent = fmt(t.armed);
    $("tel-landed").textContent = fmt(t.landed);
    $("tel-flight-mode").textContent = fmt(t.flight_mode);
    $("tel-controller").textContent = fmt(t.controller);
    const cur = pick(t, "mission_current", "mission.current", "mission_progress.current"), cnt = pick(t, "mission_count", "mission.count", "mission_progress.count");
    $("tel-mission").textContent = cnt === undefined ? fmt(pick(t, "mission_progress", "mission")) : `${fmt(cur, 0)}/${fmt(cnt, 0)}`;
    if (Array.isArray(p)) { $("tel-xy").textContent = vec(p.slice(0, 2)); $("tel-alt").textContent = fmt(p[2], 2); }
    $("tel-v").textContent = vec(t.v_W);
    $("tel-speed").textContent = fmt(norm(t.v_W));
    const rpy = pick(t, "rpy", "rpy_deg");
    $("tel-rpy").textContent = Array.isArray(rpy) ? rpy.map((x) => fmt(x * (t.rpy_deg ? 1 : 180 / Math.PI), 1)).join(", ") + " °" : "–";
    $("tel-thrust").textContent = fmt(pick(t, "thrust_margin"));
    const est = pick(t, "estimator_health", "estimator");
    $("tel-est").textContent = typeof est === "object" ? JSON.stringify(est) : fmt(est);
    $("tel-track").textContent = fmt(norm(pick(t, "tracking_error", "tracking_error_m")), 3);
    $("tel-odom").textContent = fmt(norm(pick(t, "odometry_error", "odometry_error_m")), 3);
    if ($("tel-raw").parentElement.open) $("tel-raw").textContent = JSON.stringify(t, null, 1);
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
  function drawPlot(id, series, colors, dashed) {
    const c = $(id), ctx = c.getContext("2d"), W = c.width, H = c.height;
    ctx.clearRect(0, 0, W, H);
    if (plot.t.length < 2) return;
    let lo = Infinity, hi = -Infinity;
    for (const s of series) for (const v of s) if (v !== null && isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
    if (!isFinite(lo)) return;
    if (hi - lo < 0.2) { lo -= 0.1; hi += 0.1; }
    const t0 = plot.t[plot.t.length - 1] - PLOT_S, x = (t) => ((t - t0) / PLOT_S) * W, y = (v) => H - 4 - ((v - lo) / (hi - lo)) * (H - 8);
    ctx.fillStyle = "#888"; ctx.font = "10px sans-serif";
    ctx.fillText(hi.toFixed(2), 2, 10); ctx.fillText(lo.toFixed(2), 2, H - 2);
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
             ["#d62728", "#2ca02c", "#1f77b4", "#d62728", "#2ca02c", "#1f77b4"], [0, 0, 0, 1, 1, 1]);
    drawPlot("plot-err", [plot.track, plot.odom], ["#9467bd", "#8c564b"], [0, 0]);
  }
  setInterval(drawPlots, 200);

  // Telemetry comes at up to 50 Hz and clouds at the LiDAR's rate; the 3-D view is redrawn at most ?fps= (20) times a
  // second and the panel 10 times (software WebGL and layout are what cost in a browser without a GPU).
  let lastDraw = 0, drawPending = false, dirtyPanel = false, dirtyPose = false;
  const MAX_FPS = Math.max(1, Math.min(60, parseFloat(new URLSearchParams(location.search).get("fps")) || 20));
  let DRAW_MS = 1000 / MAX_FPS;
  // A congested page (software WebGL on a busy machine) draws fewer frames: the lag of a 100 ms timer says how
  // busy the main thread is; above 30 ms the frame rate drops (to 3 at least), below 10 ms it climbs back.
  let lastTick = performance.now(), lag = 0;
  setInterval(() => {
    const now = performance.now();
    lag = 0.7 * lag + 0.3 * Math.max(0, now - lastTick - 100);
    lastTick = now;
    const fps = 1000 / DRAW_MS;
    if (lag > 30) DRAW_MS = 1000 / Math.max(3, fps * 0.7);
    else if (lag < 10) DRAW_MS = 1000 / Math.min(MAX_FPS, fps * 1.2 + 0.5);
    stats.fps = 1000 / DRAW_MS; stats.lagMs = lag;
  }, 100);
  function draw() {
    lastDraw = performance.now();
    if (dirtyPose && stats.lastTelemetry) { dirtyPose = false; placeVehicle(stats.lastTelemetry); }
    viewer.set_dirty();
  }
  function redraw() {
    const now = performance.now();
    if (now - lastDraw >= DRAW_MS) { draw(); return; }
    if (drawPending) return;
    drawPending = true;
    setTimeout(() => { drawPending = false; draw(); }, DRAW_MS - (now - lastDraw));
  }
  setInterval(() => { if (dirtyPanel && stats.lastTelemetry) { dirtyPanel = false; showTelemetry(stats.lastTelemetry); } }, 100);

  // ---- the vehicle and camera ----------------------------------------------------------------------------------
  const q4 = new THREE.Quaternion(), m4 = new THREE.Matrix4(), v3 = new THREE.Vector3(), one = new THREE.Vector3(1, 1, 1);
  let lastFollow = null;
  function toView(p) { return new THREE.Vector3(p[0], p[1], p[2]).applyMatrix4(scene.matrixWorld); }
  function placeVehicle(t) {
    const p = t.p_W, q = t.q_WB;
    if (!vehicle || !Array.isArray(p) || !Array.isArray(q)) return;
    q4.set(q[1], q[2], q[3], q[0]);
    m4.compose(v3.set(p[0], p[1], p[2]), q4, one);
    viewer.set_transform(root.concat(["vehicle"]), m4.toArray());
    const sp = targetOf(t) || setpointOf(t);
    if (sp) { setpoint.position.set(sp[0], sp[1], sp[2]); }
    if ($("follow").checked) {
      const target = toView(p);
      // keep the user's orbit offset; the first time, 2.5 m behind and 1.8 m above the vehicle
      const off = lastFollow ? viewer.camera.position.clone().sub(viewer.controls.target) : toView([-2.5, -2.5, 1.8]);
      viewer.controls.target.copy(target);
      viewer.camera.position.copy(target).add(off);
      lastFollow = target;
    } else { lastFollow = null; }
  }
  gcs.vehicleScreen = function () {  // the vehicle's pixel in the 3-D pane (CSS pixels, page coordinates)
    const t = stats.lastTelemetry;
    if (!t || !Array.isArray(t.p_W)) return null;
    scene.updateMatrixWorld(); viewer.camera.updateMatrixWorld();
    const s = toView(t.p_W).project(viewer.camera), r = viewer.renderer.domElement.getBoundingClientRect();
    return {x: r.left + (s.x + 1) / 2 * r.width, y: r.top + (1 - s.y) / 2 * r.height, z: s.z};
  };
  gcs.groundPoint = function (clientX, clientY) {  // ENU point on the ground (z = 0) under a pixel, or null
    const r = viewer.renderer.domElement.getBoundingClientRect();
    const ndc = new THREE.Vector2(((clientX - r.left) / r.width) * 2 - 1, -((clientY - r.top) / r.height) * 2 + 1);
    const ray = new THREE.Raycaster();
    scene.updateMatrixWorld(); viewer.camera.updateMatrixWorld();
    ray.setFromCamera(ndc, viewer.camera);
    const normal = new THREE.Vector3(0, 0, 1).transformDirection(scene.matrixWorld);
    const plane = new THREE.Plane().setFromNormalAndCoplanarPoint(normal, toView([0, 0, 0]));
    const hit = ray.ray.intersectPlane(plane, new THREE.Vector3());
    if (!hit) return null;
    const p = scene.worldToLocal(hit);
    return [p.x, p.y];
  };
  gcs.screenOf = function (p_W) {
    scene.updateMatrixWorld(); viewer.camera.updateMatrixWorld();
    const s = toView(p_W).project(viewer.camera), r = viewer.renderer.domElement.getBoundingClientRect();
    return {x: r.left + (s.x + 1) / 2 * r.width, y: r.top + (1 - s.y) / 2 * r.height};
  };

  function newScene(sc) {
    $("scenario").textContent = sc.scenario ? "— " + sc.scenario : "";
    addLayer("world", worldObject(sc.meshes || []));
    vehicle = addLayer("vehicle", vehicleObject(sc.arm_length || 0.15));
    viewer.set_object(root.concat(["setpoint"]), setpoint);
    // camera 4 m behind and 3 m above the origin (MeshCat's y-up camera frame: world x, world z, -world y)
    viewer.set_property(["Cameras", "default", "rotated", "<object>"], "position", [-4, 3, 4]);
    viewer.controls.target.set(0, 0, 0);
    lastFollow = null;
    applyVisibility();
  }

  // ---- event log ------------------------------------------------------------------------------------------------
  function addEvents(list) {
    const box = $("events");
    for (const e of list) {
      stats.events.push(e);
      const div = document.createElement("div");
      const kind = String(e.kind || e.type || e.level || "");
      div.className = /warn|refus|denied/i.test(kind + e.message) ? "warn" : (/crash|error|fail/i.test(kind + e.message) ? "error" : "");
      div.textContent = `${fmt(e.t, 2)} ${kind} ${e.message !== undefined ? e.message : JSON.stringify(e)}`;
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
  function onCloud(buf) {
    const a = new Float32Array(buf), n = Math.min(a[1] | 0, MAX_CLOUD);
    const attr = cloudGeom.attributes.position;
    attr.array.set(a.subarray(2, 2 + 3 * n));
    attr.needsUpdate = true;
    cloudGeom.setDrawRange(0, n);
    stats.clouds += 1;
    seen("cloud");
    redraw();
  }
  function onText(m) {
    if (m.type === "telemetry") {
      const now = performance.now();
      stats.telemetry += 1; stats.lastTelemetry = m;
      rateWindow.push(now);
      while (rateWindow.length && rateWindow[0] < now - 2000) rateWindow.shift();
      stats.rateHz = rateWindow.length > 1 ? (rateWindow.length - 1) / ((now - rateWindow[0]) / 1000) : 0;
      $("tel-rate").textContent = stats.rateHz.toFixed(0) + " Hz";
      addPlot(m); dirtyPanel = dirtyPose = true; redraw();
      seen("telemetry");
      if (Array.isArray(m.p_W)) {
        const n = flown.geometry.drawRange.count, a = flown.geometry.attributes.position.array;
        if (n === 0 || Math.hypot(m.p_W[0] - a[3 * n - 3], m.p_W[1] - a[3 * n - 2], m.p_W[2] - a[3 * n - 1]) > 0.02) appendLine(flown, m.p_W);
      }
      const c = gcs.lastClick;
      if (c && c.seenAt === undefined) {
        const tg = targetOf(m) || setpointOf(m);
        if (tg && Math.hypot(tg[0] - c.p_W[0], tg[1] - c.p_W[1]) < 0.01) { c.seenAt = now; stats.arrivals.push(now - c.t0); }
      }
    } else if (m.type === "hello") {
      stats.hellos += 1;
      newScene(m.scene);
      setLine(flown, m.path || []);
      setLine(planned, m.planned || []);
      for (const k in plot) plot[k].length = 0;
      for (const t of m.history || []) addPlot(t);
      $("events").innerHTML = ""; stats.events = [];
      addEvents(m.events || []);
      cloudGeom.setDrawRange(0, 0);  // a new run (restart) has neither the old cloud nor the old map
      if (m.esdf) onText(m.esdf); else if (layer.esdf) { viewer.delete_path(root.concat(["esdf"])); delete layer.esdf; }
      if (m.telemetry && m.telemetry.p_W) { stats.lastTelemetry = m.telemetry; showTelemetry(m.telemetry); placeVehicle(m.telemetry); }
    } else if (m.type === "events") {
      addEvents(m.events);
    } else if (m.type === "planned") {
      setLine(planned, m.planned); viewer.set_dirty();
    } else if (m.type === "esdf") {
      addLayer("esdf", esdfObject(m)); applyVisibility();
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

  // ---- controls -------------------------------------------------------------------------------------------------
  const num = (id) => parseFloat($(id).value);
  const on = (id, f) => $(id).addEventListener("click", f);
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
      $("cmd-ltl-fly").disabled = !ack.data;
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
  const canvas = viewer.renderer.domElement;
  let down = null;
  canvas.addEventListener("pointerdown", (e) => { down = [e.clientX, e.clientY]; });
  // the orbit controls take the pointer over after a press on the canvas: the release is seen by the document
  document.addEventListener("pointerup", (e) => {
    const start = down;
    down = null;
    if (!$("click-goto").checked || !start || Math.hypot(e.clientX - start[0], e.clientY - start[1]) > 4) return;
    const g = gcs.groundPoint(e.clientX, e.clientY);
    if (!g) return;
    const p = [Math.round(g[0] * 100) / 100, Math.round(g[1] * 100) / 100, num("goto-z")];
    gcs.lastClick = {t0: performance.now(), p_W: p};
    gcs.send({command: "goto", p_W: p}, (ack) => { gcs.lastClick.ackAt = performance.now(); });
  });
  connect();
})();
