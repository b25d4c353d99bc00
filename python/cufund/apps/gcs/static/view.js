// cufund web ground station: the 3-D view (three.js, from MeshCat's bundle). It is drawn in a Web Worker on an
// OffscreenCanvas: a software WebGL frame (SwiftShader, no GPU) is read back for the compositor synchronously, tens
// to hundreds of ms, and on the page's main thread that would hold up clicks, the websocket and the panel. The page
// (gcs.js) owns the camera and posts only what the view needs: the scene, poses, clouds (transferred), paths.
// Without OffscreenCanvas the page runs the same view itself (cufundView below, called in the page).
"use strict";

function softwareWebGL() {  // SwiftShader, llvmpipe...: no GPU, every pixel costs CPU (and multisampling four times)
  try {
    const probe = typeof OffscreenCanvas === "function" ? new OffscreenCanvas(1, 1) : document.createElement("canvas");
    const gl = probe.getContext("webgl");
    const info = gl && gl.getExtension("WEBGL_debug_renderer_info");
    const name = info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : "";
    if (gl && gl.getExtension("WEBGL_lose_context")) gl.getExtension("WEBGL_lose_context").loseContext();
    return /swiftshader|llvmpipe|softpipe|software/i.test(String(name));
  } catch (e) { return false; }
}

// antialias: true, false, or null (multisampled unless the WebGL renderer is a software one)
function cufundView(THREE, canvas, reply, antialias) {
  const MAX_PATH = 20000, MAX_CLOUD = 8000, PATH_STEP_M = 0.02;
  const aa = typeof antialias === "boolean" ? antialias : !softwareWebGL();
  const renderer = new THREE.WebGLRenderer({canvas: canvas, antialias: aa});
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0xeef0f4);
  const grid = new THREE.GridHelper(20, 40, 0x8a8a8a, 0xc8c8c8);  // 0.5 m cells on the ground (z = 0)
  grid.rotation.x = Math.PI / 2;
  scene.add(grid, new THREE.AxesHelper(0.5), new THREE.AmbientLight(0xffffff, 0.55));
  const sun = new THREE.DirectionalLight(0xffffff, 0.6);
  sun.position.set(1.5, 1.5, 2);
  const fill = new THREE.DirectionalLight(0xffffff, 0.3);
  fill.position.set(-1, -2, 1);
  scene.add(sun, fill);
  const camera = new THREE.PerspectiveCamera(75, 1, 0.01, 100);
  camera.up.set(0, 0, 1);  // ENU: z up

  // ---- layers ---------------------------------------------------------------------------------------------------
  const layer = {};
  function setLayer(name, object) {
    if (layer[name]) scene.remove(layer[name]);
    layer[name] = object;
    if (object) { object.visible = visible[name] !== false && (name !== "vehicle" || posed); scene.add(object); }
  }
  const visible = {};
  let posed = false;  // the vehicle is drawn once a pose came
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
  function appendLine(obj, p) {  // a point more, unless within PATH_STEP_M of the last one; the oldest half goes when full
    const attr = obj.geometry.attributes.position, a = attr.array;
    let n = obj.geometry.drawRange.count;
    if (n > 0 && Math.hypot(p[0] - a[3 * n - 3], p[1] - a[3 * n - 2], p[2] - a[3 * n - 1]) <= PATH_STEP_M) return false;
    if (n >= attr.count) { a.copyWithin(0, 3 * (attr.count >> 1)); n = attr.count - (attr.count >> 1); }
    attr.setXYZ(n, p[0], p[1], p[2]);
    attr.needsUpdate = true;
    obj.geometry.setDrawRange(0, n + 1);
    return true;
  }
  function vehicleObject(d) {
    const g = new THREE.Group();
    const mat = (c) => new THREE.MeshLambertMaterial({color: c});
    g.add(new THREE.Mesh(new THREE.BoxGeometry(0.8 * d, 0.8 * d, 0.35 * d), mat(0xd62728)));
    const nose = new THREE.Mesh(new THREE.BoxGeometry(0.5 * d, 0.15 * d, 0.15 * d), mat(0xffd700));
    nose.position.set(0.6 * d, 0, 0);
    g.add(nose);
    for (let k = 0; k < 4; k++) {
      const a = Math.PI / 4 + k * Math.PI / 2;
      const arm = new THREE.Mesh(new THREE.BoxGeometry(2 * d, 0.1 * d, 0.08 * d), mat(0x202020));
      arm.rotation.z = a;
      g.add(arm);
      const rotor = new THREE.Mesh(new THREE.CylinderGeometry(0.45 * d, 0.45 * d, 0.03 * d, 24), mat(k % 2 ? 0xff7f0e : 0x1f77b4));
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
      const seeThrough = m.label === "wall" || m.label === "ceiling";
      g.add(new THREE.Mesh(geom, new THREE.MeshLambertMaterial({
        color: new THREE.Color(m.color[0], m.color[1], m.color[2]), side: THREE.DoubleSide, transparent: seeThrough,
        opacity: m.label === "ceiling" ? 0.08 : (seeThrough ? 0.25 : 1), depthWrite: !seeThrough})));
    }
    return g;
  }
  function gatesObject(gates) {  // each detected opening as a rectangle in its plane, brighter as it is surer
    const g = new THREE.Group();
    for (const gate of gates) {
      const n = new THREE.Vector3().fromArray(gate.normal_W).normalize();
      const across = new THREE.Vector3(-n.y, n.x, 0);
      if (across.lengthSq() < 1e-9) across.set(0, 1, 0);
      across.normalize();
      const up = new THREE.Vector3().crossVectors(n, across).normalize();
      const c = new THREE.Vector3().fromArray(gate.centre_W), w = gate.size[0] / 2, h = gate.size[1] / 2;
      const corners = [[-1, -1], [1, -1], [1, 1], [-1, 1], [-1, -1]].map(([a, b]) =>
        c.clone().addScaledVector(across, a * w).addScaledVector(up, b * h));
      const geom = new THREE.BufferGeometry().setFromPoints(corners);
      const shade = 0.35 + 0.65 * Math.max(0, Math.min(1, gate.confidence));
      g.add(new THREE.Line(geom, new THREE.LineBasicMaterial({color: new THREE.Color(0.1 * shade, 0.45 * shade, shade)})));
    }
    return g;
  }
  function esdfObject(e) {  // the slice as a texture: red inside obstacles, red to green with the distance (2 m)
    const n = e.n, bytes = atob(e.d), raw = new Uint8Array(bytes.length);
    for (let i = 0; i < bytes.length; i++) raw[i] = bytes.charCodeAt(i);
    const d = new Float32Array(raw.buffer), rgba = new Uint8Array(4 * n * n);
    for (let k = 0; k < n * n; k++) {  // row j is y[j]: texture rows run up the plane like y
      const v = d[k], s = Math.max(0, Math.min(1, v / 2));
      rgba[4 * k] = v <= 0 ? 200 : 255 * (1 - s); rgba[4 * k + 1] = v <= 0 ? 0 : 255 * s; rgba[4 * k + 2] = 80; rgba[4 * k + 3] = 255;
    }
    const tex = new THREE.DataTexture(rgba, n, n, THREE.RGBAFormat);
    tex.magFilter = THREE.NearestFilter;
    tex.needsUpdate = true;
    const w = e.x[1] - e.x[0], h = e.y[1] - e.y[0];
    const mesh = new THREE.Mesh(new THREE.PlaneGeometry(w, h), new THREE.MeshBasicMaterial(
      {map: tex, transparent: true, opacity: 0.45, side: THREE.DoubleSide, depthWrite: false}));
    mesh.position.set(e.x[0] + w / 2, e.y[0] + h / 2, e.z);
    return mesh;
  }

  const flown = lineObject(0xd62728, MAX_PATH), planned = lineObject(0x1f77b4, 256);
  setLayer("flown", flown);
  setLayer("planned", planned);
  const cloudGeom = new THREE.BufferGeometry();  // one fixed buffer, refilled in place by every frame
  cloudGeom.setAttribute("position", new THREE.BufferAttribute(new Float32Array(3 * MAX_CLOUD), 3));
  cloudGeom.setDrawRange(0, 0);
  const cloud = new THREE.Points(cloudGeom, new THREE.PointsMaterial({color: 0xff8c00, size: 0.04}));
  cloud.frustumCulled = false;
  setLayer("cloud", cloud);
  const setpoint = new THREE.Mesh(new THREE.SphereGeometry(0.04, 12, 8), new THREE.MeshLambertMaterial({color: 0x2ca02c}));
  setpoint.visible = false;
  scene.add(setpoint);
  setLayer("vehicle", vehicleObject(0.15));
  const q4 = new THREE.Quaternion(), v3 = new THREE.Vector3();

  // ---- drawing on demand: at most maxFps, fewer when the machine is congested --------------------------------------
  // A new setpoint (a command's effect) is drawn at once, whatever the cap; the page is told when (epoch ms).
  let maxFps = 20, drawMs = 50, dirty = true, timer = null, lastDraw = -1e9, frames = 0, lag = 0, lastTick = performance.now();
  let markerMoved = null, askedAt = 0, frameLag = 0;
  const waiting = [];
  function draw() {
    timer = null;
    if (askedAt) {  // how late the frame came: the display pipeline (software rasteriser, compositor) is behind
      frameLag = 0.7 * frameLag + 0.3 * Math.max(0, performance.now() - askedAt - 17);
      askedAt = 0;
    }
    if (!dirty) return;
    dirty = false;
    const t = performance.now();
    renderer.render(scene, camera);
    lastDraw = performance.now();
    frames += 1;
    if (waiting.length) {  // answered when the next frame begins: this one has gone to the compositor by then
      const ids = waiting.splice(0), value = {frames: frames, renderMs: lastDraw - t};
      nextFrame(() => { for (const id of ids) reply({type: "reply", id: id, value: value}); });
    }
    if (markerMoved) { reply({type: "marker", sp: markerMoved, at: performance.timeOrigin + lastDraw}); markerMoved = null; }
  }
  // frames are drawn in the animation-frame callbacks of the thread the view runs in (a worker's are in step with
  // the display it draws to), at most every drawMs
  const nextFrame = typeof requestAnimationFrame === "function" ? requestAnimationFrame : (f) => setTimeout(f, 0);
  function redraw(now) {
    dirty = true;
    if (now && timer !== null) { clearTimeout(timer); timer = null; }
    if (timer === null) {
      timer = setTimeout(() => { askedAt = performance.now(); nextFrame(draw); },
                         now ? 0 : Math.max(0, lastDraw + drawMs - performance.now()));
    }
  }
  setInterval(() => {  // the lag of a 100 ms timer (this thread busy) or of frames: above 30 ms fewer frames (3 at least)
    const now = performance.now();
    lag = 0.7 * lag + 0.3 * Math.max(0, now - lastTick - 100);
    lastTick = now;
    const fps = 1000 / drawMs, congestion = Math.max(lag, frameLag);
    if (congestion > 30) drawMs = 1000 / Math.max(3, fps * 0.7);
    else if (congestion < 10) drawMs = 1000 / Math.min(maxFps, fps * 1.2 + 0.5);
    frameLag *= 0.9;  // forgotten while no frame is drawn
    reply({type: "stats", fps: 1000 / drawMs, lagMs: congestion, frames: frames, antialias: aa});
  }, 100);

  function pointsOf(obj) {
    const g = obj.geometry, a = g.attributes.position.array, out = [];
    for (let i = 0; i < g.drawRange.count; i++) out.push([a[3 * i], a[3 * i + 1], a[3 * i + 2]]);
    return out;
  }

  return function handle(m) {
    switch (m.type) {
      case "size":
        renderer.setPixelRatio(m.dpr);
        renderer.setSize(m.w, m.h, false);
        camera.aspect = m.w / Math.max(1, m.h);
        camera.updateProjectionMatrix();
        break;
      case "camera":
        camera.position.set(m.p[0], m.p[1], m.p[2]);
        camera.fov = m.fov;
        camera.lookAt(m.target[0], m.target[1], m.target[2]);
        camera.updateProjectionMatrix();
        break;
      case "scene":  // a new run: its world and vehicle; neither the old cloud nor the old map
        setLayer("world", worldObject(m.meshes || []));
        setLayer("vehicle", vehicleObject(m.arm_length || 0.15));
        posed = false;
        setLayer("esdf", null);
        cloudGeom.setDrawRange(0, 0);
        setpoint.visible = false;
        break;
      case "path": setLine(flown, m.points); break;
      case "planned": setLine(planned, m.points); break;
      case "pose": {
        const v = layer.vehicle;
        if (Array.isArray(m.p) && Array.isArray(m.q)) {
          v.position.set(m.p[0], m.p[1], m.p[2]);
          v.quaternion.copy(q4.set(m.q[1], m.q[2], m.q[3], m.q[0]));
          posed = true;
          v.visible = visible.vehicle !== false;
          appendLine(flown, m.p);
        }
        if (Array.isArray(m.sp) && (!setpoint.visible || setpoint.position.distanceToSquared(v3.fromArray(m.sp)) > 1e-8)) {
          setpoint.position.fromArray(m.sp);
          setpoint.visible = true;
          markerMoved = m.sp;
          redraw(true);
          return;
        }
        break;
      }
      case "cloud": {  // float32 [t, n, x, y, z, ...] in the world frame
        const a = new Float32Array(m.buf), n = Math.min(a[1] | 0, MAX_CLOUD, (a.length - 2) / 3 | 0);
        const attr = cloudGeom.attributes.position;
        attr.array.set(a.subarray(2, 2 + 3 * n));
        attr.needsUpdate = true;
        cloudGeom.setDrawRange(0, n);
        break;
      }
      case "esdf": setLayer("esdf", m.esdf ? esdfObject(m.esdf) : null); break;
      case "gates": setLayer("gates", gatesObject(m.gates || [])); break;
      case "visible":
        Object.assign(visible, m.layers);
        for (const k in layer) if (layer[k]) layer[k].visible = visible[k] !== false && (k !== "vehicle" || posed);
        break;
      case "fps": maxFps = Math.max(1, Math.min(60, m.fps)); drawMs = 1000 / maxFps; break;
      case "points": reply({type: "reply", id: m.id, value: layer[m.layer] ? pointsOf(layer[m.layer]) : null}); return;
      case "drawn": waiting.push(m.id); break;  // answered after the next frame
      default: return;
    }
    redraw();
  };
}

if (typeof document === "undefined" && typeof importScripts === "function") {  // the Web Worker
  // MeshCat's bundle (its three.js) touches the DOM while it loads (dat.gui's style sheet); a worker has none, so
  // whatever it asks of one is absorbed while it loads, then taken away again.
  const absorb = new Proxy(function () {}, {
    get: (t, k) => (k === Symbol.toPrimitive ? () => "" : k === Symbol.hasInstance ? () => false
      : k === Symbol.iterator ? undefined : absorb),
    apply: () => absorb, construct: () => absorb, set: () => true});
  const shimmed = ["window", "document"];
  self.window = self;
  self.document = absorb;
  for (let i = 0; ; i++) {
    try { importScripts("/meshcat/main.min.js"); break; } catch (e) {
      const missing = /^(\w+) is not defined/.exec(e.message);
      if (!missing || i > 20) throw e;
      self[missing[1]] = absorb;
      shimmed.push(missing[1]);
    }
  }
  for (const k of shimmed) delete self[k];
  let handle = null;
  const queue = [];
  self.onmessage = (e) => {
    const m = e.data;
    if (m.type === "init") {
      handle = cufundView(MeshCat.THREE, m.canvas, (r) => self.postMessage(r), m.antialias);
      for (const q of queue.splice(0)) handle(q);
    } else if (handle) handle(m); else queue.push(m);
  };
}
