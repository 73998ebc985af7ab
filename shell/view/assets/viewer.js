// flexshell view: draws the scene that shell/view/page.py embeds as JSON (arrays in base64), with three.js.
// Bodies are posed per frame from the stored body poses; flexible bodies are deformed here, per frame:
// x_i = l0_i + s * sum_k eta_k gamma_k,i (translation mode shapes times modal coordinates), so the file
// holds the shapes once and the modal coordinates per frame. Query parameters (used by the tests):
// ?t=SECONDS shows that instant paused, &scale=S sets the deformation scale, &follow=0 stops following.
(function () {
  "use strict";
  const marks = { start: performance.now() };
  const S = JSON.parse(document.getElementById("scene-data").textContent);
  marks.parsed = performance.now();

  function decode(a) {
    if (a === null || a === undefined) return null;
    const t0 = performance.now();
    const text = atob(a.b64), n = text.length, bytes = new Uint8Array(n);
    for (let i = 0; i < n; i++) bytes[i] = text.charCodeAt(i);
    const T = { f4: Float32Array, f8: Float64Array, i4: Int32Array }[a.dtype];
    marks.decoding = (marks.decoding || 0) + performance.now() - t0;
    return new T(bytes.buffer);
  }
  const query = new URLSearchParams(window.location.search);
  const time = decode(S.time);
  const F = time.length;
  const L = S.length;

  // ---- renderer, camera, lights ------------------------------------------------------------------------
  const host = document.getElementById("view");
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setClearColor(0x1b1f27);
  host.insertBefore(renderer.domElement, host.firstChild);
  marks.renderer = performance.now();
  const scene = new THREE.Scene();
  const camera = new THREE.PerspectiveCamera(45, 1, L * 1e-3, L * 1e5);
  camera.up.set(0, 0, 1);
  const C = S.center || [0, 0, 0];
  camera.position.set(C[0] + 1.1 * L, C[1] - 1.4 * L, C[2] + 0.85 * L);
  const controls = new THREE.OrbitControls(camera, renderer.domElement);
  controls.target.set(C[0], C[1], C[2]);
  scene.add(new THREE.AmbientLight(0xffffff, 0.55));
  const sun = new THREE.DirectionalLight(0xffffff, 0.75);
  sun.position.set(1, -1.5, 2);
  scene.add(sun);
  const palette = [0x8fb3d9, 0xd9b38f, 0x9fd98f, 0xd98fb3, 0xc6c6c6, 0xb39fd9, 0x8fd9d0];

  function triad(size) {
    const g = new THREE.Group();
    const colors = [0xff5555, 0x55dd55, 0x5599ff];
    const dirs = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];
    for (let k = 0; k < 3; k++) {
      const geometry = new THREE.BufferGeometry();
      geometry.setAttribute("position", new THREE.Float32BufferAttribute([0, 0, 0].concat(dirs[k].map((v) => v * size)), 3));
      g.add(new THREE.Line(geometry, new THREE.LineBasicMaterial({ color: colors[k] })));
    }
    return g;
  }
  function quaternion(array, f) {
    return new THREE.Quaternion(array[4 * f], array[4 * f + 1], array[4 * f + 2], array[4 * f + 3]);
  }

  // ---- bodies --------------------------------------------------------------------------------------------
  const bodies = S.bodies.map((b, index) => {
    const group = new THREE.Group();
    const color = palette[index % palette.length];
    const item = { group, kind: b.kind, position: decode(b.position), quaternion: decode(b.quaternion) };
    if (b.kind === "box") {
      const box = decode(b.box), center = decode(b.box_center), q = decode(b.box_quaternion);
      const geometry = new THREE.BoxGeometry(box[0], box[1], box[2]);
      const mesh = new THREE.Mesh(geometry, new THREE.MeshStandardMaterial({ color, roughness: 0.7, metalness: 0.1, transparent: true, opacity: 0.6, depthWrite: false }));
      const edges = new THREE.LineSegments(new THREE.EdgesGeometry(geometry), new THREE.LineBasicMaterial({ color: 0x11151b }));
      const holder = new THREE.Group();
      holder.add(mesh, edges);
      holder.position.set(center[0], center[1], center[2]);
      holder.quaternion.copy(quaternion(q, 0));
      group.add(holder);
    } else {
      const vertices = decode(b.vertices);
      const geometry = new THREE.BufferGeometry();
      const positions = new Float32Array(vertices);
      geometry.setAttribute("position", new THREE.BufferAttribute(positions, 3));
      item.rest = vertices; item.positions = positions; item.geometries = [];
      const faces = decode(b.faces);
      if (faces && faces.length) {
        const g = geometry.clone();
        g.setAttribute("position", geometry.getAttribute("position"));
        g.setIndex(new THREE.BufferAttribute(new Uint32Array(faces), 1));
        g.computeVertexNormals();
        group.add(new THREE.Mesh(g, new THREE.MeshStandardMaterial({
          color, roughness: 0.75, metalness: 0.05, side: THREE.DoubleSide,
          polygonOffset: true, polygonOffsetFactor: 1, polygonOffsetUnits: 1 })));
        item.geometries.push(g);
      }
      const edges = decode(b.edges);
      if (edges && edges.length) {
        const g = new THREE.BufferGeometry();
        g.setAttribute("position", geometry.getAttribute("position"));
        g.setIndex(new THREE.BufferAttribute(new Uint32Array(edges), 1));
        group.add(new THREE.LineSegments(g, new THREE.LineBasicMaterial({ color: b.kind === "flexible" ? 0xf0f4f8 : 0x11151b })));
      }
      if (b.kind === "flexible") {
        const points = new THREE.Points(geometry, new THREE.PointsMaterial({ color: 0xffd27a, size: 3, sizeAttenuation: false }));
        group.add(points);
        item.shapes = decode(b.shapes);
        item.eta = decode(b.eta);
        item.n = b.n_modes;
        item.attribute = geometry.getAttribute("position");
      }
    }
    group.add(triad(0.12 * L));
    scene.add(group);
    return item;
  });

  marks.bodies = performance.now();
  // ---- nodes, wheels, thrusters, track -------------------------------------------------------------------
  const nodes = S.nodes.map((n) => {
    const group = new THREE.Group();
    group.add(triad((n.hinge ? 0.1 : 0.07) * L));
    if (n.hinge) group.add(new THREE.Mesh(new THREE.SphereGeometry(0.015 * L, 12, 8),
                                         new THREE.MeshBasicMaterial({ color: 0xffe066 })));
    scene.add(group);
    return { group, position: decode(n.position), quaternion: decode(n.quaternion) };
  });
  const wheelCount = {};
  const wheels = S.wheels.map((w) => {
    const axis = decode(w.axis);
    const mount = new THREE.Group();  // local z along the spin axis
    mount.quaternion.setFromUnitVectors(new THREE.Vector3(0, 0, 1), new THREE.Vector3(axis[0], axis[1], axis[2]).normalize());
    const k = (wheelCount[w.node] = (wheelCount[w.node] || 0) + 1);
    const radius = 0.055 * L;
    const spin = new THREE.Group();
    const disk = new THREE.Mesh(new THREE.CylinderGeometry(radius, radius, 0.25 * radius, 28),
      new THREE.MeshStandardMaterial({ color: 0x707b8c, roughness: 0.4, metalness: 0.6 }));
    disk.rotation.x = Math.PI / 2;  // cylinder axis (y) onto z
    const stripe = new THREE.Mesh(new THREE.BoxGeometry(1.9 * radius, 0.25 * radius, 0.3 * radius),
      new THREE.MeshStandardMaterial({ color: 0xffb347 }));
    spin.add(disk, stripe);
    spin.position.z = 0.09 * L + 0.02 * L * k;
    mount.add(spin);
    nodes[w.node].group.add(mount);
    return { spin, angle: decode(w.angle) };
  });
  const thrusters = S.thrusters.map((t) => {
    const p = decode(t.position), d = decode(t.direction);
    const mount = new THREE.Group();
    mount.position.set(p[0], p[1], p[2]);
    // local +y along the exhaust (opposite to the force direction)
    mount.quaternion.setFromUnitVectors(new THREE.Vector3(0, 1, 0), new THREE.Vector3(-d[0], -d[1], -d[2]).normalize());
    const size = 0.035 * L;
    const nozzle = new THREE.Mesh(new THREE.ConeGeometry(0.4 * size, size, 12),
      new THREE.MeshStandardMaterial({ color: 0x9aa3ad, metalness: 0.5, roughness: 0.4 }));
    nozzle.position.y = 0.5 * size;
    nozzle.rotation.x = Math.PI;
    const plume = new THREE.Mesh(new THREE.ConeGeometry(0.55 * size, 4 * size, 14, 1, true),
      new THREE.MeshBasicMaterial({ color: 0xffa030, transparent: true, opacity: 0.75, side: THREE.DoubleSide }));
    plume.geometry.translate(0, -2 * size, 0);
    plume.rotation.x = Math.PI;
    plume.position.y = size;
    plume.visible = false;
    mount.add(nozzle, plume);
    nodes[t.node].group.add(mount);
    return { plume, level: decode(t.level) };
  });
  const trackBody = bodies[S.track_body];
  const origin0 = [trackBody.position[0], trackBody.position[1], trackBody.position[2]];
  const trackPoints = new Float32Array(3 * F);
  for (let f = 0; f < F; f++) for (let a = 0; a < 3; a++) trackPoints[3 * f + a] = trackBody.position[3 * f + a] - origin0[a];
  const trackGeometry = new THREE.BufferGeometry();
  trackGeometry.setAttribute("position", new THREE.BufferAttribute(trackPoints, 3));
  const track = new THREE.Line(trackGeometry, new THREE.LineBasicMaterial({ color: 0x66ccff, transparent: true, opacity: 0.7 }));
  scene.add(track);

  // ---- signal panel --------------------------------------------------------------------------------------
  const plotColors = ["#ff6b6b", "#6bdc6b", "#6ba8ff", "#ffd36b", "#d68bff", "#6bdcd3", "#ff9f6b", "#c0c0c0"];
  const plots = S.signals.map((s) => {
    const canvas = document.createElement("canvas");
    document.getElementById("plots").appendChild(canvas);
    const t = decode(s.time), v = decode(s.values), m = s.labels.length, n = t.length;
    let lo = Infinity, hi = -Infinity;
    for (let i = 0; i < v.length; i++) if (isFinite(v[i])) { lo = Math.min(lo, v[i]); hi = Math.max(hi, v[i]); }
    if (!(hi > lo)) { lo -= 1; hi += 1; }
    const pad = 0.06 * (hi - lo);
    return { canvas, s, t, v, m, n, lo: lo - pad, hi: hi + pad, background: null };
  });
  function drawPlotBackground(p) {
    const w = p.canvas.clientWidth || 380, h = 170, ratio = window.devicePixelRatio || 1;
    p.canvas.width = w * ratio; p.canvas.height = h * ratio; p.canvas.style.height = h + "px";
    const c = p.canvas.getContext("2d");
    c.setTransform(ratio, 0, 0, ratio, 0, 0);
    c.fillStyle = "#20252f"; c.fillRect(0, 0, w, h);
    const x0 = 54, x1 = w - 8, y0 = 22, y1 = h - 22;
    p.box = [x0, x1, y0, y1, w, h];
    const t0 = time[0], t1 = time[F - 1] > time[0] ? time[F - 1] : time[0] + 1;
    const X = (t) => x0 + (x1 - x0) * (t - t0) / (t1 - t0), Y = (y) => y1 - (y1 - y0) * (y - p.lo) / (p.hi - p.lo);
    p.X = X;
    c.strokeStyle = "#3a4350"; c.lineWidth = 1; c.strokeRect(x0, y0, x1 - x0, y1 - y0);
    c.fillStyle = "#aab4c0"; c.font = "11px system-ui, sans-serif";
    for (let k = 0; k <= 2; k++) {
      const y = p.lo + (p.hi - p.lo) * k / 2;
      c.fillText(y.toPrecision(3), 4, Y(y) + 4);
    }
    c.fillText(t0.toPrecision(4) + " s", x0, h - 6);
    const right = t1.toPrecision(4) + " s"; c.fillText(right, x1 - c.measureText(right).width, h - 6);
    c.fillStyle = "#dde3ea"; c.font = "12px system-ui, sans-serif";
    c.fillText(p.s.name + (p.s.unit && p.s.unit !== "1" ? " [" + p.s.unit + "]" : ""), x0, 14);
    let lx = x1;
    for (let j = p.m - 1; j >= 0 && p.m <= 8; j--) {
      const label = p.s.labels[j]; lx -= c.measureText(label).width + 8;
      c.fillStyle = plotColors[j % plotColors.length]; c.fillText(label, lx, 14);
    }
    c.save(); c.beginPath(); c.rect(x0, y0, x1 - x0, y1 - y0); c.clip();
    for (let j = 0; j < p.m; j++) {
      c.strokeStyle = plotColors[j % plotColors.length]; c.lineWidth = 1.2; c.beginPath();
      for (let i = 0; i < p.n; i++) {
        const x = X(p.t[i]), y = Y(p.v[j * p.n + i]);
        if (i === 0) c.moveTo(x, y); else c.lineTo(x, y);
      }
      c.stroke();
    }
    c.restore();
    p.background = c.getImageData(0, 0, p.canvas.width, p.canvas.height);
  }
  function drawCursor(p, t) {
    const c = p.canvas.getContext("2d");
    c.putImageData(p.background, 0, 0);
    const x = p.X(t);
    c.strokeStyle = "#ffffff"; c.lineWidth = 1; c.beginPath(); c.moveTo(x, p.box[2]); c.lineTo(x, p.box[3]); c.stroke();
  }
  const notes = document.getElementById("notes");
  for (const note of S.notes) { const li = document.createElement("li"); li.textContent = note; notes.appendChild(li); }
  document.getElementById("title").textContent = S.title;
  if (!plots.length && !S.notes.length) document.getElementById("panel").style.display = "none";

  // ---- state and frame update ----------------------------------------------------------------------------
  const state = { t: time[0], playing: false, speed: 1, scale: S.deformation_scale, follow: true, frame: -1, alpha: 0 };
  function frameAt(t) {  // last frame at or before t
    let lo = 0, hi = F - 1;
    if (t <= time[0]) return 0;
    if (t >= time[hi]) return hi;
    while (hi - lo > 1) { const mid = (lo + hi) >> 1; if (time[mid] <= t) lo = mid; else hi = mid; }
    return lo;
  }
  function deform(b, f, g, a) {  // x = l0 + s sum_k eta_k gamma_k, eta interpolated between frames f and g
    const n = b.n, eta = b.eta, shapes = b.shapes, rest = b.rest, out = b.positions, m = rest.length;
    out.set(rest);
    for (let k = 0; k < n; k++) {
      const e = state.scale * ((1 - a) * eta[f * n + k] + a * eta[g * n + k]);
      if (e === 0) continue;
      const base = k * m;
      for (let i = 0; i < m; i++) out[i] += e * shapes[base + i];
    }
    b.attribute.needsUpdate = true;
    for (const g of b.geometries) g.computeVertexNormals();
  }
  function lerp3(array, f, g, a, k) {
    return array[3 * f + k] + a * (array[3 * g + k] - array[3 * f + k]);
  }
  function update(force) {
    // between frames f and g = f + 1 (a mode shape: the last frame is followed by the first), linearly
    // (positions, modal coordinates, wheel angles) and by slerp (attitudes); a thruster holds frame f
    const f = frameAt(state.t);
    const g = f + 1 < F ? f + 1 : (S.loop && F > 1 ? 0 : f);
    const tg = g === f ? time[f] : (g === 0 ? time[F - 1] + (time[1] - time[0]) : time[g]);
    const a = tg > time[f] ? Math.min(1, Math.max(0, (state.t - time[f]) / (tg - time[f]))) : 0;
    if (f !== state.frame || a !== state.alpha || force) {
      state.frame = f; state.alpha = a;
      const o = state.follow ? [0, 1, 2].map((k) => lerp3(trackBody.position, f, g, a, k)) : origin0;
      for (const b of bodies) {
        b.group.position.set(lerp3(b.position, f, g, a, 0) - o[0], lerp3(b.position, f, g, a, 1) - o[1],
                             lerp3(b.position, f, g, a, 2) - o[2]);
        b.group.quaternion.copy(quaternion(b.quaternion, f).slerp(quaternion(b.quaternion, g), a));
        if (b.kind === "flexible") deform(b, f, g, a);
      }
      for (const n of nodes) {
        n.group.position.set(lerp3(n.position, f, g, a, 0) - o[0], lerp3(n.position, f, g, a, 1) - o[1],
                             lerp3(n.position, f, g, a, 2) - o[2]);
        n.group.quaternion.copy(quaternion(n.quaternion, f).slerp(quaternion(n.quaternion, g), a));
      }
      for (const w of wheels) if (w.angle) w.spin.rotation.z = ((1 - a) * w.angle[f] + a * w.angle[g]) % (2 * Math.PI);
      for (const th of thrusters) {
        const level = th.level ? th.level[f] : 0;
        th.plume.visible = level > 0.01;
        th.plume.scale.set(0.4 + 0.6 * level, 0.3 + 0.7 * level, 0.4 + 0.6 * level);
      }
      track.position.set(origin0[0] - o[0], origin0[1] - o[1], origin0[2] - o[2]);
    }
    for (const p of plots) if (p.background) drawCursor(p, state.t);
    document.getElementById("clock").textContent = "t = " + state.t.toFixed(3) + " s  (" + (f + 1) + "/" + F + ")";
    const span = time[F - 1] - time[0];
    document.getElementById("slider").value = span > 0 ? Math.round(1000 * (state.t - time[0]) / span) : 0;
    renderer.render(scene, camera);
  }

  // ---- controls ------------------------------------------------------------------------------------------
  const playButton = document.getElementById("play");
  function setPlaying(on) { state.playing = on; playButton.textContent = on ? "Pause" : "Play"; }
  playButton.onclick = () => {
    if (!state.playing && state.t >= time[F - 1]) state.t = time[0];
    setPlaying(!state.playing);
  };
  document.getElementById("slider").oninput = (e) => {
    state.t = time[0] + (time[F - 1] - time[0]) * e.target.value / 1000; setPlaying(false); update();
  };
  const speed = document.getElementById("speed");
  const span = time[F - 1] - time[0];
  // a mode shape: one period in about 2 s of wall time (slow motion for a fast mode), else real time
  const period = F > 1 ? span + (time[1] - time[0]) : 1;
  const natural = S.loop ? [0.25, 0.5, 1, 2, 4].map((k) => +(k * period / 2).toPrecision(3))
                         : [0.1, 0.5, 1, 2, 5, 10, 30, 100];
  for (const v of natural) { const o = document.createElement("option"); o.value = v; o.textContent = v + "x"; speed.appendChild(o); }
  state.speed = S.loop ? natural[2] : (span > 120 ? 10 : 1);
  if (!natural.includes(state.speed)) { const o = document.createElement("option"); o.value = state.speed; o.textContent = state.speed.toPrecision(2) + "x"; speed.appendChild(o); }
  speed.value = state.speed;
  speed.onchange = () => { state.speed = parseFloat(speed.value); };
  const scaleInput = document.getElementById("scale");
  scaleInput.value = state.scale;
  if (!bodies.some((b) => b.kind === "flexible")) scaleInput.parentElement.style.display = "none";
  scaleInput.onchange = () => { const v = parseFloat(scaleInput.value); if (v >= 0) { state.scale = v; update(true); } };
  const follow = document.getElementById("follow");
  follow.onchange = () => { state.follow = follow.checked; update(true); };
  document.getElementById("fit").onclick = () => {
    let r = L;
    for (let f = 0; f < F; f++) r = Math.max(r, Math.hypot(trackPoints[3 * f] , trackPoints[3 * f + 1], trackPoints[3 * f + 2]));
    follow.checked = state.follow = false;
    controls.target.set(0, 0, 0);
    camera.position.set(1.2 * r, -1.5 * r, 1.0 * r);
    update(true);
  };
  document.getElementById("legend").textContent = "frames: body (long axes), hinge (yellow dot), nodes (short axes): x red, y green, z blue";

  function resize() {
    const w = host.clientWidth, h = host.clientHeight;
    renderer.setSize(w, h);
    camera.aspect = w / Math.max(h, 1);
    camera.updateProjectionMatrix();
    for (const p of plots) drawPlotBackground(p);
    update(true);
  }
  window.addEventListener("resize", resize);
  controls.addEventListener("change", () => renderer.render(scene, camera));

  if (query.has("scale")) { state.scale = parseFloat(query.get("scale")); scaleInput.value = state.scale; }
  if (query.has("follow")) { state.follow = query.get("follow") !== "0"; follow.checked = state.follow; }
  if (query.has("t")) state.t = parseFloat(query.get("t"));
  marks.built = performance.now();
  resize();
  marks.drawn = performance.now();
  if (!query.has("t") && F > 1) setPlaying(true);

  let last = performance.now();
  function tick(now) {
    const dt = Math.min(0.1, (now - last) / 1000); last = now;
    if (state.playing) {
      state.t += dt * state.speed;
      if (state.t > time[F - 1]) {
        if (S.loop) state.t = time[0] + (state.t - time[0]) % period;
        else { state.t = time[F - 1]; setPlaying(false); }
      }
      update();
    }
    requestAnimationFrame(tick);
  }
  requestAnimationFrame(tick);
  window.flexshellView = { state, update, frames: F, ready: true };
  if (query.has("probe")) {  // the tests read what the page computed: frame, deformed grids, body poses
    const probe = document.createElement("pre");
    probe.id = "probe";
    probe.textContent = JSON.stringify({
      frame: state.frame, alpha: state.alpha, scale: state.scale, load_ms: performance.now(), marks,
      flexible: bodies.filter((b) => b.kind === "flexible").map((b) => Array.from(b.positions)),
      bodies: bodies.map((b) => [b.group.position.toArray(), b.group.quaternion.toArray()]),
      wheels: wheels.map((w) => w.spin.rotation.z),
      plumes: thrusters.map((t) => t.plume.visible),
    });
    document.body.appendChild(probe);
  }
  document.title = S.title;
})();
