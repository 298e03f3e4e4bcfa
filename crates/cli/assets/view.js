// armature's result viewer: the arm along the dense trajectory, the task's geometry, playback
// controls and a readout against the limits. Reads the JSON in #armature-data (see
// crates/cli/src/view/); three.js comes from the bundle as globalThis.ARMATURE_THREE.
'use strict';
(function () {
  const { THREE, OrbitControls } = globalThis.ARMATURE_THREE;
  const data = JSON.parse(document.getElementById('armature-data').textContent);
  const traj = data.trajectory;
  const times = traj.time.map((r) => r[0]);
  const T = times[times.length - 1];
  const scene = data.scene || null;
  const $ = (id) => document.getElementById(id);

  // ---- sampling: the dense trajectory between its samples --------------------------------

  /** Sample index k and fraction a with t = (1 − a)·times[k] + a·times[k+1]. */
  function sampleAt(t) {
    if (!(t > times[0])) return { k: 0, a: 0 };
    if (t >= T) return { k: times.length - 1, a: 0 };
    let lo = 0;
    let hi = times.length - 1;
    while (hi - lo > 1) {
      const mid = (lo + hi) >> 1;
      if (times[mid] <= t) lo = mid; else hi = mid;
    }
    const a = (t - times[lo]) / (times[hi] - times[lo]);
    return a === 1 ? { k: hi, a: 0 } : { k: lo, a };
  }

  /** A series' row at (k, a), linear between samples (exact at the samples). */
  function row(name, s) {
    const rows = traj[name];
    if (!rows) return null;
    const r0 = rows[s.k];
    if (s.a === 0) return r0.slice();
    const r1 = rows[s.k + 1];
    return r0.map((v, i) => v + s.a * (r1[i] - v));
  }

  const q0 = new THREE.Quaternion();
  const q1 = new THREE.Quaternion();
  const p0 = new THREE.Vector3();
  const p1 = new THREE.Vector3();
  const sc = new THREE.Vector3();

  /** A 4×4 frame series (row-major) at (k, a): translation lerped, rotation slerped. */
  function frame(name, s, out) {
    const rows = traj[name];
    out.set(...rows[s.k]);
    if (s.a === 0) return out;
    const m1 = new THREE.Matrix4().set(...rows[s.k + 1]);
    out.decompose(p0, q0, sc);
    m1.decompose(p1, q1, sc);
    p0.lerp(p1, s.a);
    q0.slerp(q1, s.a);
    return out.compose(p0, q0, new THREE.Vector3(1, 1, 1));
  }

  // ---- the three.js world -----------------------------------------------------------------

  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setSize(window.innerWidth, window.innerHeight);
  renderer.setClearColor(0xf4f5f7);
  $('view').appendChild(renderer.domElement);
  const world = new THREE.Scene();
  const camera = new THREE.PerspectiveCamera(40, window.innerWidth / window.innerHeight, 0.005, 100);
  camera.up.set(0, 0, 1);
  const controls = new OrbitControls(camera, renderer.domElement);
  world.add(new THREE.HemisphereLight(0xffffff, 0x8090a0, 1.6));
  const sun = new THREE.DirectionalLight(0xffffff, 1.6);
  sun.position.set(2, -3, 5);
  world.add(sun);

  const material = (color, opacity) => new THREE.MeshStandardMaterial({
    color, roughness: 0.6, metalness: 0.05,
    transparent: opacity < 1, opacity, depthWrite: opacity >= 1,
  });
  const v3 = (a) => new THREE.Vector3(a[0], a[1], a[2]);
  const Y = new THREE.Vector3(0, 1, 0);

  /** Places a unit-height Y-aligned mesh between a and b. */
  function between(mesh, a, b) {
    const d = new THREE.Vector3().subVectors(b, a);
    const len = Math.max(d.length(), 1e-9);
    mesh.position.copy(a).addScaledVector(d, 0.5);
    mesh.quaternion.setFromUnitVectors(Y, d.divideScalar(len));
    mesh.scale.set(1, len, 1);
  }

  /** A capsule of radius r whose ends follow two points (a cylinder and two balls). */
  function capsule(r, mat) {
    const group = new THREE.Group();
    const body = new THREE.Mesh(new THREE.CylinderGeometry(r, r, 1, 24, 1, true), mat);
    const ends = [0, 1].map(() => new THREE.Mesh(new THREE.SphereGeometry(r, 24, 12), mat));
    group.add(body, ...ends);
    group.userData.set = (a, b) => {
      between(body, a, b);
      ends[0].position.copy(a);
      ends[1].position.copy(b);
    };
    return group;
  }

  // ---- the task's static geometry ---------------------------------------------------------

  const bounds = new THREE.Box3();
  const labels = [];

  function addLabel(text, position) {
    const same = labels.find((l) => l.position.distanceTo(position) < 1e-6);
    if (same) {
      same.el.textContent = `${same.el.textContent}, ${text}`;
      return;
    }
    const el = document.createElement('div');
    el.className = 'label';
    el.textContent = text;
    $('labels').appendChild(el);
    labels.push({ el, position });
  }

  function addObstacle(o) {
    const mat = material(0xd9534f, 0.55);
    let mesh;
    if (o.kind === 'sphere') {
      mesh = new THREE.Mesh(new THREE.SphereGeometry(o.radius, 40, 20), mat);
      mesh.position.copy(v3(o.center));
    } else if (o.kind === 'box') {
      const h = o.half_extents;
      mesh = new THREE.Mesh(new THREE.BoxGeometry(2 * h[0], 2 * h[1], 2 * h[2]), mat);
      const r = o.rotation;
      const m = new THREE.Matrix4().set(r[0], r[1], r[2], o.center[0], r[3], r[4], r[5], o.center[1],
        r[6], r[7], r[8], o.center[2], 0, 0, 0, 1);
      mesh.applyMatrix4(m);
    } else if (o.kind === 'capsule') {
      mesh = capsule(o.radius, mat);
      mesh.userData.set(v3(o.a), v3(o.b));
    } else if (o.kind === 'half_space') {
      return { halfSpace: o, name: o.name };
    } else {
      throw new Error('unknown obstacle kind ' + o.kind);
    }
    world.add(mesh);
    bounds.expandByObject(mesh);
    addLabel(o.name, mesh.position.clone());
    return null;
  }

  /** A large translucent plane: the table, or a half-space's boundary. */
  function addPlane(normal, offset, color, extent) {
    const n = v3(normal).normalize();
    const plane = new THREE.Mesh(new THREE.PlaneGeometry(extent, extent),
      new THREE.MeshStandardMaterial({ color, transparent: true, opacity: 0.45, side: THREE.DoubleSide, depthWrite: false }));
    plane.quaternion.setFromUnitVectors(new THREE.Vector3(0, 0, 1), n);
    const c = bounds.getCenter(new THREE.Vector3());
    plane.position.copy(c).addScaledVector(n, offset - n.dot(c));
    world.add(plane);
    return plane;
  }

  function addWaypoint(w) {
    const p = v3(w.position);
    const dot = new THREE.Mesh(new THREE.SphereGeometry(0.004, 12, 8), material(0x1b5e20, 1));
    dot.position.copy(p);
    const ball = new THREE.Mesh(new THREE.SphereGeometry(w.tolerance, 24, 12), material(0x43a047, 0.3));
    ball.position.copy(p);
    world.add(dot, ball);
    bounds.expandByPoint(p);
    let label = w.name;
    if (w.orientation) {
      addCone(p, w.orientation);
      label += ` (±${w.orientation.tolerance_deg}°)`;
    }
    addLabel(label, p);
  }

  /** The gripper-axis directions an orientation tolerance allows: a cone around the desired
   * axis (a rotation within θ of R moves every axis by at most θ), opening towards the side
   * the arm reaches from, with the desired axis drawn through it. */
  function addCone(p, o) {
    const r = o.rotation;
    const t = scene.tool_axis;
    const axis = new THREE.Vector3(r[0] * t[0] + r[1] * t[1] + r[2] * t[2],
      r[3] * t[0] + r[4] * t[1] + r[5] * t[2], r[6] * t[0] + r[7] * t[1] + r[8] * t[2]).normalize();
    const h = 0.08;
    const radius = h * Math.tan((o.tolerance_deg * Math.PI) / 180);
    const cone = new THREE.Mesh(new THREE.ConeGeometry(Math.max(radius, 1e-5), h, 32, 1, true),
      new THREE.MeshStandardMaterial({ color: 0xf9a825, transparent: true, opacity: 0.45, side: THREE.DoubleSide, depthWrite: false }));
    // ConeGeometry's apex is at +y·h/2: point it at the waypoint, opening along −axis.
    cone.quaternion.setFromUnitVectors(Y, axis);
    cone.position.copy(p).addScaledVector(axis, -h / 2);
    const line = new THREE.Line(new THREE.BufferGeometry().setFromPoints([p, p.clone().addScaledVector(axis, -1.25 * h)]),
      new THREE.LineBasicMaterial({ color: 0xe65100 }));
    world.add(cone, line);
  }

  // ---- the moving parts -------------------------------------------------------------------

  const keypoints = scene ? scene.keypoints : [];
  const frameNames = scene ? [] : Object.keys(traj).filter((n) => traj[n][0].length === 16);
  const kpPositions = keypoints.map(() => new THREE.Vector3());
  const m4 = new THREE.Matrix4();

  function keypointsAt(s) {
    keypoints.forEach((kp, i) => {
      frame(kp.frame, s, m4);
      kpPositions[i].set(kp.offset[0], kp.offset[1], kp.offset[2]).applyMatrix4(m4);
    });
    return kpPositions;
  }

  const links = scene ? scene.links.map((l) => ({
    link: l,
    mesh: capsule(l.radius, material(l.collision ? 0x5b7db1 : 0x444c56, 1)),
  })) : [];
  links.forEach((l) => world.add(l.mesh));
  const joints = keypoints.map(() => {
    const m = new THREE.Mesh(new THREE.SphereGeometry(0.012, 16, 8), material(0x263238, 1));
    world.add(m);
    return m;
  });
  /** A frame as three thin rods: x red, y green, z blue. */
  function axes(length, radius) {
    const group = new THREE.Group();
    const o = new THREE.Vector3();
    [[1, 0, 0, 0xd32f2f], [0, 1, 0, 0x388e3c], [0, 0, 1, 0x1976d2]].forEach(([x, y, z, color]) => {
      const rod = new THREE.Mesh(new THREE.CylinderGeometry(radius, radius, 1, 8), material(color, 1));
      between(rod, o, new THREE.Vector3(x, y, z).multiplyScalar(length));
      group.add(rod);
    });
    group.matrixAutoUpdate = false;
    world.add(group);
    return group;
  }
  const eeAxes = axes(0.08, 0.0025);
  let frameAxes = [];

  /** A tube through `points` coloured by `values` in [0, 1] (blue → red), each ring taking
   * the value of the polyline at the ring's arc length. */
  function tube(points, values, radius) {
    const length = [0];
    for (let i = 1; i < points.length; i++) length.push(length[i - 1] + points[i].distanceTo(points[i - 1]));
    const total = length[length.length - 1];
    if (!(total > 0)) return new THREE.Group();
    const curve = new THREE.CatmullRomCurve3(points, false, 'centripetal');
    const segments = Math.min(4 * points.length, 2000);
    const radial = 8;
    const geometry = new THREE.TubeGeometry(curve, segments, radius, radial, false);
    const colors = [];
    const color = new THREE.Color();
    let j = 0;
    for (let i = 0; i <= segments; i++) {
      const at = (i / segments) * total;
      while (j < length.length - 2 && length[j + 1] < at) j += 1;
      const span = length[j + 1] - length[j];
      const f = span > 0 ? Math.min(Math.max((at - length[j]) / span, 0), 1) : 0;
      const v = values[j] + f * (values[j + 1] - values[j]);
      color.setHSL((240 - 240 * v) / 360, 0.85, 0.48);
      for (let r = 0; r <= radial; r++) colors.push(color.r, color.g, color.b);
    }
    geometry.setAttribute('color', new THREE.Float32BufferAttribute(colors, 3));
    return new THREE.Mesh(geometry, new THREE.MeshStandardMaterial({ vertexColors: true, roughness: 0.7 }));
  }

  /** The end-effector path, coloured by speed (blue slow → red fast). */
  function speedPath() {
    const ee = traj.ee_position;
    if (!ee) return null;
    const speed = ee.map((_, i) => {
      const a = Math.max(i - 1, 0);
      const b = Math.min(i + 1, ee.length - 1);
      const dt = times[b] - times[a];
      return dt > 0 ? v3(ee[b]).distanceTo(v3(ee[a])) / dt : 0;
    });
    const max = Math.max(...speed, 1e-9);
    world.add(tube(ee.map(v3), speed.map((v) => v / max), 0.0025));
    ee.forEach((p) => bounds.expandByPoint(v3(p)));
    $('legend').innerHTML = '<div>end-effector speed</div><div class="ramp"></div>' +
      `<div class="ends"><span>0 m/s</span><span>${max.toFixed(2)} m/s</span></div>`;
    return max;
  }

  /** The guess (dashed) and the SCvx iterates (grey, darker when later), hidden at first. */
  function iterateLines() {
    const group = new THREE.Group();
    group.visible = false;
    const its = data.iterates || [];
    const last = Math.max(its.length - 1, 1);
    its.forEach((it, i) => {
      const geometry = new THREE.BufferGeometry().setFromPoints(it.ee.map(v3));
      const line = it.iteration === 0
        ? new THREE.Line(geometry, new THREE.LineDashedMaterial({ color: 0xef6c00, dashSize: 0.015, gapSize: 0.01 }))
        : new THREE.Line(geometry, new THREE.LineBasicMaterial({ color: new THREE.Color().setHSL(0.6, 0.3, 0.8 - 0.5 * (i / last)) }));
      if (it.iteration === 0) line.computeLineDistances();
      group.add(line);
    });
    world.add(group);
    const box = $('iterates');
    if (its.length === 0) {
      box.disabled = true;
      $('iterates-label').textContent = 'guess and iterates (the result holds none)';
    } else {
      $('iterates-label').textContent = `guess (dashed) and ${its.length - 1} iterates`;
    }
    box.addEventListener('change', () => { group.visible = box.checked; });
  }

  // ---- readout ----------------------------------------------------------------------------

  const fmt = (v, d) => (Math.abs(v) < 1e-12 ? 0 : v).toFixed(d);

  function jointTable() {
    if (!scene || !traj.angle) return;
    const head = '<tr><th>joint</th><th>angle</th><th>velocity</th><th>torque</th></tr>';
    $('joints').innerHTML = head + scene.joints.map((j, i) =>
      `<tr><td>${j.name}</td><td id="ja${i}"></td><td id="jv${i}"></td><td id="jt${i}"></td></tr>`).join('');
  }

  /** Fraction of the way from the middle of [lo, hi] to the nearer limit, signed. */
  const rangeFraction = (v, lo, hi) => (hi > lo ? (2 * v - lo - hi) / (hi - lo) : 0);

  function cell(id, fraction, text) {
    const el = $(id);
    const f = Math.min(Math.abs(fraction), 1);
    el.className = Math.abs(fraction) >= 0.999 ? 'hot' : '';
    el.innerHTML = `<span class="bar" style="width:${(24 * f).toFixed(1)}px"></span>${text}`;
    el.title = `${(100 * fraction).toFixed(1)} % of the limit`;
  }

  function readJoints(s) {
    if (!scene || !traj.angle) return;
    const q = row('angle', s);
    const v = row('velocity', s);
    const tau = row('torque', s);
    scene.joints.forEach((j, i) => {
      cell('ja' + i, rangeFraction(q[i], j.angle[0], j.angle[1]), fmt(q[i], 3));
      if (v) cell('jv' + i, v[i] / j.velocity, `${fmt((100 * v[i]) / j.velocity, 0)}%`);
      if (tau) cell('jt' + i, tau[i] / j.torque, `${fmt((100 * tau[i]) / j.torque, 0)}%`);
    });
  }

  /** The closest pair at (k, a): its distance, its name and whether it is under the margin. */
  function closest(s) {
    const c = scene && scene.clearance;
    const d = c && row('clearance', s);
    if (!d) return null;
    let best = 0;
    d.forEach((v, i) => { if (v < d[best]) best = i; });
    return { value: d[best], pair: c.pairs[best], index: best, under: d[best] < c.margin - 1e-9 };
  }

  function readout(t, s) {
    const parts = [`<div>t = <span id="time" data-value="${t}">${t.toFixed(3)}</span> s of ${T.toFixed(3)} s</div>`];
    const c = closest(s);
    if (c) {
      parts.push(`<div class="${c.under ? 'warn' : ''}">closest clearance <span id="clearance" data-value="${c.value}" data-pair="${c.pair}">` +
        `${(1000 * c.value).toFixed(3)} mm</span> (${c.pair}; margin ${(1000 * scene.clearance.margin).toFixed(1)} mm)</div>`);
    } else if (scene) {
      parts.push('<div>closest clearance: the task has no collision pairs</div>');
    }
    if (scene && scene.table_height !== null && scene.table_height !== undefined && traj.ee_position) {
      const z = row('ee_position', s)[2] - scene.table_height;
      parts.push(`<div class="${z < -1e-9 ? 'warn' : ''}">end effector above the table: ${(1000 * z).toFixed(1)} mm</div>`);
    }
    $('readout').innerHTML = parts.join('');
    readJoints(s);
    return c;
  }

  // ---- one frame --------------------------------------------------------------------------

  function pose(t) {
    const s = sampleAt(t);
    if (scene) {
      const p = keypointsAt(s);
      links.forEach(({ link, mesh }) => mesh.userData.set(p[link.start], p[link.end]));
      joints.forEach((m, i) => m.position.copy(p[i]));
    }
    if (traj.ee_pose) {
      frame('ee_pose', s, m4);
      eeAxes.matrix.copy(m4);
      eeAxes.matrixWorldNeedsUpdate = true;
    } else {
      eeAxes.visible = false;
    }
    frameNames.forEach((name, i) => {
      frame(name, s, frameAxes[i].matrix);
      frameAxes[i].matrixWorldNeedsUpdate = true;
    });
    const c = readout(t, s);
    links.forEach(({ link, mesh }) => {
      const near = c && c.pair.split('|').includes(link.name);
      mesh.children.forEach((m) => m.material.emissive.setHex(near ? (c.under ? 0x801010 : 0x5a3a00) : 0));
    });
  }

  const projected = new THREE.Vector3();
  function placeLabels() {
    labels.forEach(({ el, position }) => {
      projected.copy(position).project(camera);
      const visible = projected.z < 1;
      el.style.display = visible ? '' : 'none';
      el.style.left = `${((projected.x + 1) / 2) * window.innerWidth}px`;
      el.style.top = `${((1 - projected.y) / 2) * window.innerHeight}px`;
    });
  }

  let frames = 0;
  function render() {
    renderer.render(world, camera);
    placeLabels();
    frames += 1;
    document.body.dataset.frames = String(frames);
    if (frames === 1) document.body.dataset.firstFrameMs = performance.now().toFixed(1);
  }

  // ---- setup ------------------------------------------------------------------------------

  function summary() {
    const cls = data.status === 'converged' ? 'status-converged' : 'status-other';
    const robot = scene ? ` · ${scene.robot}` : '';
    let text = `<span class="${cls}">${data.status}</span> · T = ${data.final_time.toFixed(4)} s · ${data.iterations} iterations${robot}`;
    const v = data.max_violation;
    if (v && typeof v.value === 'number') {
      const at = typeof v.time === 'number' ? ` at t = ${v.time.toFixed(3)} s` : '';
      text += `<div style="font-weight:400">largest violation: ${v.constraint} = ${v.value.toExponential(2)}${at}</div>`;
    }
    $('summary').innerHTML = text;
  }

  /** Leaves the panel's strip on the left free: the image shifts right by half its width. */
  function viewOffset() {
    const panel = $('panel').getBoundingClientRect();
    const w = window.innerWidth;
    const h = window.innerHeight;
    camera.clearViewOffset();
    if (panel.right < 0.5 * w) camera.setViewOffset(w, h, -panel.right / 2, 0, w, h);
    camera.updateProjectionMatrix();
  }

  function fitCamera() {
    if (scene) {
      const step = Math.max(1, Math.floor(times.length / 40));
      for (let k = 0; k < times.length; k += step) keypointsAt({ k, a: 0 }).forEach((p) => bounds.expandByPoint(p));
    }
    frameNames.forEach((name) => traj[name].forEach((r) => bounds.expandByPoint(new THREE.Vector3(r[3], r[7], r[11]))));
    if (bounds.isEmpty()) bounds.set(new THREE.Vector3(-0.5, -0.5, -0.5), new THREE.Vector3(0.5, 0.5, 0.5));
    const c = bounds.getCenter(new THREE.Vector3());
    const size = Math.max(bounds.getSize(new THREE.Vector3()).length(), 0.2);
    camera.position.copy(c).add(new THREE.Vector3(0.8, -1.35, 0.75).multiplyScalar(size * 1.0));
    controls.target.copy(c);
    viewOffset();
    controls.update();
    return size;
  }

  function build() {
    summary();
    const halfSpaces = scene ? scene.obstacles.map(addObstacle).filter(Boolean) : [];
    if (scene) scene.waypoints.forEach(addWaypoint);
    speedPath();
    iterateLines();
    jointTable();
    const size = fitCamera();
    frameAxes = frameNames.map(() => axes(0.12 * size, 0.004 * size));
    if (scene && scene.table_height !== null && scene.table_height !== undefined) {
      addPlane([0, 0, 1], scene.table_height, 0xb0a58c, 3 * size);
      const grid = new THREE.GridHelper(3 * size, 30, 0x8d8370, 0xc8bfa8);
      grid.rotation.x = Math.PI / 2;
      grid.position.set(bounds.getCenter(new THREE.Vector3()).x, bounds.getCenter(new THREE.Vector3()).y, scene.table_height + 1e-4);
      world.add(grid);
    }
    halfSpaces.forEach((h) => addPlane(h.halfSpace.normal, h.halfSpace.offset, 0xd9534f, 2 * size));
    frameNames.forEach((name) => {
      const path = traj[name].map((r) => new THREE.Vector3(r[3], r[7], r[11]));
      world.add(new THREE.Line(new THREE.BufferGeometry().setFromPoints(path), new THREE.LineBasicMaterial({ color: 0x5b7db1 })));
      addLabel(name, path[0]);
    });
    if (!scene && frameNames.length > 0) {
      const grid = new THREE.GridHelper(2 * size, 20, 0x8a9099, 0xb4b9c0);
      grid.rotation.x = Math.PI / 2;
      const c = bounds.getCenter(new THREE.Vector3());
      grid.position.set(c.x, c.y, bounds.min.z);
      world.add(grid);
    }
    if (!scene && frameNames.length === 0) {
      const m = $('message');
      m.hidden = false;
      m.innerHTML = '<b>Nothing to draw.</b> This result has no robot geometry (it is not from a task file) and no ' +
        'frames: outputs of 4×4 transforms. Add frame outputs to the problem file, or give the task with ' +
        '<code>armature view RESULT --task TASK -o view.html</code>.';
    }
  }

  // ---- playback ---------------------------------------------------------------------------

  const slider = $('slider');
  slider.max = String(T);
  let t = 0;
  let playing = true;
  let last = null;

  function setTime(value) {
    t = Math.min(Math.max(value, 0), T);
    slider.value = String(t);
    pose(t);
  }

  function setPlaying(on) {
    playing = on;
    $('play').textContent = on ? 'pause' : 'play';
    last = null;
  }

  /** `#t=SECONDS` or `#t=closest` (the instant of the smallest clearance) opens paused there;
   * `#iterates` (alone or after `&`) shows the guess and the iterates. */
  function fromHash() {
    if (/(?:^#|&)iterates(?:&|$)/.test(window.location.hash) && !$('iterates').disabled) {
      $('iterates').checked = true;
      $('iterates').dispatchEvent(new Event('change'));
    }
    const m = /(?:^#|&)t=([^&]+)/.exec(window.location.hash);
    if (!m) return false;
    if (m[1] === 'closest') {
      let best = null;
      times.forEach((time, k) => {
        const c = closest({ k, a: 0 });
        if (c && (best === null || c.value < best.value)) best = { value: c.value, time };
      });
      setTime(best ? best.time : 0);
    } else {
      // As a user would: move the slider and let its input handler do the rest.
      slider.value = m[1];
      slider.dispatchEvent(new Event('input'));
    }
    setPlaying(false);
    return true;
  }

  function tick(now) {
    if (playing) {
      if (last !== null) {
        let next = t + ((now - last) / 1000) * Number($('speed').value);
        if (next > T) next = 0;
        setTime(next);
      }
      last = now;
    }
    controls.update();
    render();
    requestAnimationFrame(tick);
  }

  build();
  $('play').addEventListener('click', () => setPlaying(!playing));
  slider.addEventListener('input', () => { setPlaying(false); setTime(Number(slider.value)); });
  window.addEventListener('keydown', (e) => {
    if (e.code === 'Space' && e.target.tagName !== 'SELECT') { e.preventDefault(); setPlaying(!playing); }
  });
  window.addEventListener('hashchange', fromHash);
  window.addEventListener('resize', () => {
    camera.aspect = window.innerWidth / window.innerHeight;
    viewOffset();
    renderer.setSize(window.innerWidth, window.innerHeight);
  });
  if (!fromHash()) setTime(0);
  render();
  requestAnimationFrame(tick);
})();
