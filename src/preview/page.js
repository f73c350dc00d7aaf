// idexp preview: the page's script (embedded by src/preview/page.rs).
// three.js comes from the <script type="text/plain"> elements above as blob
// modules, so the page needs no network and no server.
const $ = (id) => document.getElementById(id);
const state = { ready: false };
window.idexpState = state;

function fail(e) {
  $('error').textContent = 'preview error: ' + (e && e.stack ? e.stack : e);
  state.error = String(e);
  $('idexp-state').textContent = JSON.stringify(state);
}

async function loadThree() {
  const url = (text) => URL.createObjectURL(new Blob([text], { type: 'text/javascript' }));
  const core = url($('three-core').textContent);
  const mod = url($('three-module').textContent.split('"./three.core.min.js"').join(JSON.stringify(core)));
  const orbit = url($('three-orbit').textContent.split("from 'three'").join('from ' + JSON.stringify(mod)));
  const THREE = await import(mod);
  const { OrbitControls } = await import(orbit);
  return { THREE, OrbitControls };
}

function bytes(b64) {
  const s = atob(b64);
  const out = new Uint8Array(s.length);
  for (let i = 0; i < s.length; i++) out[i] = s.charCodeAt(i);
  return out.buffer;
}
const F64 = (b) => new Float64Array(bytes(b));
const F32 = (b) => new Float32Array(bytes(b));
const I32 = (b) => new Int32Array(bytes(b));

const fmt = (v, d = 4) => (v === null || v === undefined || !isFinite(v) ? '—' : v.toFixed(d));
const SEG_COLORS = { lead: '#8a93a3', period: ['#2e86c1', '#3f9bd6'] };
function segName(s) {
  if (s === -2147483648) return '';
  if (s === 0) return 'lead-in';
  if (s === -1) return 'lead-out';
  return 'period ' + s;
}

const marks = {};
const mark = (name) => { marks[name] = Math.round(performance.now()); };
async function main() {
  mark('start');
  const D = JSON.parse($('idexp-data').textContent);
  mark('json');
  const n = D.dof;
  const F = D.frames;
  const N = F.n;
  const T = F64(F.t), SEG = I32(F.segment), Q = F64(F.q), QD = F64(F.qd), LINKS = F32(F.links), EE = F32(F.ee);
  const CL = {};
  for (const c of ['self', 'world']) CL[c] = { pair: I32(F[c].pair), dist: F64(F[c].distance), w: F32(F[c].witness) };
  mark('decode');
  const { THREE, OrbitControls } = await loadThree();
  mark('three');

  // ---------------------------------------------------------------- scene
  const view = $('view');
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  view.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0xffffff);
  const camera = new THREE.PerspectiveCamera(40, 1, 0.01, 100);
  camera.up.set(0, 0, 1);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x8890a0, 1.6));
  const sun = new THREE.DirectionalLight(0xffffff, 1.6);
  sun.position.set(2, -3, 5);
  scene.add(sun);

  // reach of the motion: link origins over every frame
  let reach = 0.3;
  for (let i = 0; i < N * n; i++) {
    const o = i * 7;
    reach = Math.max(reach, Math.hypot(LINKS[o], LINKS[o + 1], LINKS[o + 2]));
  }
  reach += 0.25;

  const groups = { robot: new THREE.Group(), cell: new THREE.Group(), path: new THREE.Group(), workspace: new THREE.Group(), pairs: new THREE.Group(), skeleton: new THREE.Group() };
  for (const g of Object.values(groups)) scene.add(g);

  // floor and planes: a grid on each plane, 2·reach wide
  const planeNames = [];
  for (const p of D.planes) {
    const nrm = new THREE.Vector3(...p.normal).normalize();
    const g = new THREE.Group();
    const grid = new THREE.GridHelper(4 * reach, 20, 0x9aa3b2, 0xd5d9e0);
    grid.rotation.x = Math.PI / 2; // the helper lies in x-z; make it x-y
    g.add(grid);
    const sheet = new THREE.Mesh(new THREE.PlaneGeometry(4 * reach, 4 * reach), new THREE.MeshBasicMaterial({ color: 0xeef0f3, transparent: true, opacity: 0.55, side: THREE.DoubleSide, depthWrite: false }));
    g.add(sheet);
    g.quaternion.setFromUnitVectors(new THREE.Vector3(0, 0, 1), nrm);
    g.position.copy(nrm.clone().multiplyScalar(p.offset - 1e-4));
    groups.cell.add(g);
    planeNames.push(p.name);
  }

  if (!D.planes.length) {
    // no floor is checked: a faint reference grid at z = 0 for orientation
    const grid = new THREE.GridHelper(4 * reach, 20, 0xd5d9e0, 0xeceef2);
    grid.rotation.x = Math.PI / 2;
    groups.cell.add(grid);
  }

  // bodies: each convex part as drawn by idexp (padding included)
  const linkGroups = [];
  for (let l = 0; l < n; l++) {
    const g = new THREE.Group();
    linkGroups.push(g);
    groups.robot.add(g);
  }
  const robotMat = new THREE.MeshStandardMaterial({ color: 0xb8c2d1, metalness: 0.05, roughness: 0.7, flatShading: true });
  const baseMat = new THREE.MeshStandardMaterial({ color: 0x8e99ab, metalness: 0.05, roughness: 0.8, flatShading: true });
  const obstacleMat = new THREE.MeshStandardMaterial({ color: 0xd8a657, roughness: 0.8, transparent: true, opacity: 0.6, flatShading: true });
  const edgeMat = new THREE.LineBasicMaterial({ color: 0x5d6b82, transparent: true, opacity: 0.35 });
  const bodyMeshes = [];
  D.bodies.forEach((b, bi) => {
    const parent = b.link === null ? (b.obstacle ? groups.cell : groups.robot) : linkGroups[b.link];
    const mat = b.obstacle ? obstacleMat : b.link === null ? baseMat : robotMat;
    const meshes = [];
    for (const part of b.parts) {
      const geo = new THREE.BufferGeometry();
      geo.setAttribute('position', new THREE.BufferAttribute(F32(part.vertices), 3));
      geo.setIndex(new THREE.BufferAttribute(new Uint32Array(I32(part.triangles).buffer), 1));
      geo.computeVertexNormals();
      const m = new THREE.Mesh(geo, mat.clone());
      m.userData.body = bi;
      parent.add(m);
      const edges = new THREE.LineSegments(new THREE.EdgesGeometry(geo, 25), edgeMat);
      parent.add(edges);
      meshes.push(m);
    }
    bodyMeshes.push(meshes);
  });

  // skeleton: link origins joined to their parents' (drawn always; the
  // only picture of a robot without collision geometry)
  const skelGeo = new THREE.BufferGeometry();
  skelGeo.setAttribute('position', new THREE.BufferAttribute(new Float32Array(n * 6), 3));
  groups.skeleton.add(new THREE.LineSegments(skelGeo, new THREE.LineBasicMaterial({ color: 0x2c3e50 })));
  const jointDots = [];
  for (let l = 0; l < n; l++) {
    const s = new THREE.Mesh(new THREE.SphereGeometry(0.012, 12, 8), new THREE.MeshBasicMaterial({ color: 0x2c3e50 }));
    groups.skeleton.add(s);
    jointDots.push(s);
  }

  // end-effector path, coloured by segment
  {
    const pos = new Float32Array(N * 3);
    const col = new Float32Array(N * 3);
    const cLead = new THREE.Color(0x9aa3b2), cPer = new THREE.Color(0xe67e22);
    for (let k = 0; k < N; k++) {
      pos.set(EE.subarray(3 * k, 3 * k + 3), 3 * k);
      const c = SEG[k] >= 1 ? cPer : cLead;
      col.set([c.r, c.g, c.b], 3 * k);
    }
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(pos, 3));
    g.setAttribute('color', new THREE.BufferAttribute(col, 3));
    groups.path.add(new THREE.Line(g, new THREE.LineBasicMaterial({ vertexColors: true })));
  }
  const eeDot = new THREE.Mesh(new THREE.SphereGeometry(0.015, 16, 12), new THREE.MeshBasicMaterial({ color: 0xe67e22 }));
  groups.path.add(eeDot);

  // closest pairs: segment between the witness points and a dot at each end
  const pairViz = {};
  for (const [c, color] of [['self', 0xc0392b], ['world', 0x1f6fd1]]) {
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(6), 3));
    const line = new THREE.Line(g, new THREE.LineBasicMaterial({ color, depthTest: false }));
    line.renderOrder = 10;
    const dots = [0, 1].map(() => {
      const s = new THREE.Mesh(new THREE.SphereGeometry(0.008, 12, 8), new THREE.MeshBasicMaterial({ color, depthTest: false }));
      s.renderOrder = 10;
      groups.pairs.add(s);
      return s;
    });
    groups.pairs.add(line);
    pairViz[c] = { line, dots, color };
  }

  // workspace volumes of the design
  const wsMat = (color) => new THREE.MeshBasicMaterial({ color, transparent: true, opacity: 0.08, depthWrite: false, side: THREE.DoubleSide });
  const wsLine = (color) => new THREE.LineBasicMaterial({ color, transparent: true, opacity: 0.7 });
  for (const w of D.workspace || []) {
    const s = w.shape;
    const kind = s.type;
    const p = s;
    const inside = kind !== 'outside_box';
    const color = inside ? 0x27ae60 : 0xc0392b;
    const add = (geo, at) => {
      const m = new THREE.Mesh(geo, wsMat(color));
      const e = new THREE.LineSegments(new THREE.EdgesGeometry(geo), wsLine(color));
      if (at) { m.position.copy(at); e.position.copy(at); }
      groups.workspace.add(m, e);
    };
    if (kind === 'box' || kind === 'outside_box') {
      const c = p.clearance || 0;
      const size = [0, 1, 2].map((i) => p.max[i] - p.min[i] + 2 * c);
      add(new THREE.BoxGeometry(...size), new THREE.Vector3(...[0, 1, 2].map((i) => (p.max[i] + p.min[i]) / 2)));
    } else if (kind === 'sphere') {
      add(new THREE.SphereGeometry(p.radius, 32, 16), new THREE.Vector3(...p.center));
    } else if (kind === 'half_space') {
      const nrm = new THREE.Vector3(...p.normal).normalize();
      const m = new THREE.Mesh(new THREE.PlaneGeometry(2 * reach, 2 * reach), wsMat(color));
      m.quaternion.setFromUnitVectors(new THREE.Vector3(0, 0, 1), nrm);
      m.position.copy(nrm.clone().multiplyScalar(p.offset));
      groups.workspace.add(m);
    } else if (kind === 'sector') {
      const [a0, a1] = p.azimuth, [r0, r1] = p.radius, [z0, z1] = p.z;
      const pts = [];
      const ring = (r, z) => {
        for (let i = 0; i < 48; i++) {
          const u = a0 + ((a1 - a0) * i) / 48, v = a0 + ((a1 - a0) * (i + 1)) / 48;
          pts.push(r * Math.cos(u), r * Math.sin(u), z, r * Math.cos(v), r * Math.sin(v), z);
        }
      };
      for (const r of [r0, r1]) for (const z of [z0, z1]) ring(r, z);
      for (const a of [a0, a1]) for (const r of [r0, r1]) pts.push(r * Math.cos(a), r * Math.sin(a), z0, r * Math.cos(a), r * Math.sin(a), z1);
      for (const a of [a0, a1]) for (const z of [z0, z1]) pts.push(r0 * Math.cos(a), r0 * Math.sin(a), z, r1 * Math.cos(a), r1 * Math.sin(a), z);
      const g = new THREE.BufferGeometry();
      g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(pts), 3));
      const e = new THREE.LineSegments(g, wsLine(color));
      e.position.set(...p.center);
      groups.workspace.add(e);
    }
  }

  // camera and orbit controls
  camera.position.set(1.05 * reach, -1.35 * reach, 0.85 * reach);
  const controls = new OrbitControls(camera, renderer.domElement);
  controls.target.set(0, 0, 0.35 * reach);
  controls.update();
  controls.addEventListener('change', () => render());

  function resize() {
    const w = view.clientWidth, h = view.clientHeight;
    renderer.setSize(w, h, false);
    renderer.domElement.style.width = w + 'px';
    renderer.domElement.style.height = h + 'px';
    camera.aspect = w / Math.max(h, 1);
    camera.updateProjectionMatrix();
    render();
  }
  function render() {
    renderer.render(scene, camera);
  }

  mark('scene');
  // ---------------------------------------------------------------- panel
  $('title').textContent = D.title;
  $('meta').innerHTML = '';
  const meta = [
    `robot ${D.robot}, ${n} joints; ${D.rows} trajectory rows scanned, ${N} frames`,
    D.margin === null ? 'no collision geometry: skeleton only' : `${D.pairs.length} checked pairs (${D.excluded_pairs} excluded), margin ${D.margin} m; distances above ${fmt(D.cap, 2)} m not resolved`,
    `limits: ${D.limits_source}; end effector: ${D.end_effector}`,
    `geometry: convex parts as idexp checks them (padding included); idexp ${D.idexp_version}, three.js ${D.three_version}`,
  ];
  for (const m of meta) {
    const d = document.createElement('div');
    d.textContent = m;
    $('meta').appendChild(d);
  }
  const toggles = [['robot', 'robot'], ['skeleton', 'skeleton'], ['path', 'path'], ['pairs', 'closest pairs'], ['workspace', 'workspace'], ['cell', 'floor & cell']];
  for (const [key, label] of toggles) {
    const l = document.createElement('label');
    const c = document.createElement('input');
    c.type = 'checkbox';
    c.checked = true;
    c.id = 'show-' + key;
    c.addEventListener('change', () => { groups[key].visible = c.checked; render(); });
    l.append(c, ' ' + label);
    $('toggles').appendChild(l);
  }
  for (const ins of D.instants) {
    const b = document.createElement('button');
    const title = document.createElement('b');
    title.textContent = `${ins.label} — t = ${ins.t.toFixed(3)} s`;
    const small = document.createElement('small');
    small.textContent = ins.detail;
    b.append(title, small);
    b.addEventListener('click', () => { pause(); setFrame(ins.frame); });
    $('instants').appendChild(b);
  }
  if (!D.instants.length) $('instants').textContent = 'none';

  // phase bar
  const t0 = T[0], t1 = T[N - 1], span = Math.max(t1 - t0, 1e-9);
  for (const s of D.segments) {
    const d = document.createElement('div');
    d.style.left = (100 * (s.t0 - t0)) / span + '%';
    d.style.width = (100 * (s.t1 - s.t0)) / span + '%';
    d.style.background = s.segment >= 1 ? SEG_COLORS.period[s.segment % 2] : SEG_COLORS.lead;
    // a narrow segment (many periods) shows its number only
    d.textContent = s.t1 - s.t0 < 0.06 * span ? (s.segment >= 1 ? String(s.segment) : '') : s.name;
    d.title = `${s.name}: ${s.t0.toFixed(3)} – ${s.t1.toFixed(3)} s`;
    $('phases').appendChild(d);
  }
  for (const ins of D.instants) {
    const m = document.createElement('i');
    m.style.left = (100 * (ins.t - t0)) / span + '%';
    m.title = ins.label;
    $('phases').appendChild(m);
  }

  // plots: one per joint, position and velocity, limits as bands
  const plots = [];
  function makePlot(host, j, kind) {
    const c = document.createElement('canvas');
    c.className = 'plot';
    host.appendChild(c);
    const jt = D.joints[j];
    const lim = kind === 'q' ? jt.position : [jt.velocity === null ? null : -jt.velocity, jt.velocity];
    const hard = kind === 'q' ? jt.hard : [jt.hard_velocity === null ? null : -jt.hard_velocity, jt.hard_velocity];
    const data = kind === 'q' ? Q : QD;
    let lo = Infinity, hi = -Infinity;
    for (let k = 0; k < N; k++) { const v = data[k * n + j]; lo = Math.min(lo, v); hi = Math.max(hi, v); }
    for (const v of [...lim]) if (v !== null && Math.abs(v) < 1e3) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
    const pad = 0.08 * Math.max(hi - lo, 1e-6);
    const p = { c, j, kind, lim, hard, data, lo: lo - pad, hi: hi + pad, bg: null };
    c.addEventListener('click', (e) => {
      const r = c.getBoundingClientRect();
      const x = (e.clientX - r.left) / r.width;
      pause();
      setTime(t0 + x * span);
    });
    plots.push(p);
  }
  for (let j = 0; j < n; j++) makePlot($('plots-q'), j, 'q');
  for (let j = 0; j < n; j++) makePlot($('plots-qd'), j, 'qd');
  function drawPlotBg(p) {
    // drawn once into an offscreen canvas; the cursor is drawn over a copy
    const dpr = window.devicePixelRatio || 1;
    const W = Math.max(1, Math.round(p.c.clientWidth * dpr)), H = Math.max(1, Math.round(p.c.clientHeight * dpr));
    p.c.width = W; p.c.height = H;
    const c = document.createElement('canvas');
    c.width = W; c.height = H;
    const g = c.getContext('2d');
    const L = 46 * dpr, R = 4 * dpr, TOP = 14 * dpr, B = 4 * dpr;
    const X = (t) => L + ((t - t0) / span) * (W - L - R);
    const Y = (v) => TOP + (1 - (v - p.lo) / (p.hi - p.lo)) * (H - TOP - B);
    g.fillStyle = '#fff'; g.fillRect(0, 0, W, H);
    // segment boundaries
    g.strokeStyle = '#e3e6eb'; g.lineWidth = 1;
    for (const s of D.segments) { g.beginPath(); g.moveTo(X(s.t0), TOP); g.lineTo(X(s.t0), H - B); g.stroke(); }
    // allowed band
    const [a, b] = p.lim;
    const ya = a === null ? H - B : Math.min(H - B, Math.max(TOP, Y(a)));
    const yb = b === null ? TOP : Math.min(H - B, Math.max(TOP, Y(b)));
    g.fillStyle = 'rgba(39,174,96,0.10)'; g.fillRect(L, yb, W - L - R, ya - yb);
    g.strokeStyle = 'rgba(39,174,96,0.7)';
    for (const v of p.lim) if (v !== null && v > p.lo && v < p.hi) { g.beginPath(); g.moveTo(L, Y(v)); g.lineTo(W - R, Y(v)); g.stroke(); }
    g.strokeStyle = 'rgba(192,57,43,0.8)'; g.setLineDash([4 * dpr, 3 * dpr]);
    for (const v of p.hard) if (v !== null && v > p.lo && v < p.hi) { g.beginPath(); g.moveTo(L, Y(v)); g.lineTo(W - R, Y(v)); g.stroke(); }
    g.setLineDash([]);
    // the series: its range per pixel column (min to max; every sample is
    // in it), joined column to column
    g.strokeStyle = '#1d2433'; g.lineWidth = 1.2 * dpr; g.beginPath();
    let col = -1, lo = 0, hi = 0, first = true;
    const flush = () => {
      if (col < 0) return;
      if (first) { g.moveTo(col, Y(lo)); first = false; } else g.lineTo(col, Y(lo));
      if (hi !== lo) g.lineTo(col, Y(hi));
    };
    for (let k = 0; k < N; k++) {
      const x = Math.round(X(T[k])), v = p.data[k * n + p.j];
      if (x !== col) { flush(); col = x; lo = v; hi = v; } else { lo = Math.min(lo, v); hi = Math.max(hi, v); }
    }
    flush();
    g.stroke();
    // labels
    const jt = D.joints[p.j];
    const unit = p.kind === 'q' ? jt.unit : jt.unit + '/s';
    g.fillStyle = '#3b4557'; g.font = `${10 * dpr}px system-ui, sans-serif`;
    g.fillText(`${p.kind}${p.j + 1} ${jt.name} [${unit}]`, L, 10 * dpr);
    g.textAlign = 'right';
    g.fillText(p.hi.toFixed(2), L - 3 * dpr, TOP + 8 * dpr);
    g.fillText(p.lo.toFixed(2), L - 3 * dpr, H - B);
    g.textAlign = 'left';
    p.bg = c;
    p.X = X; p.Y = Y;
  }
  function drawPlotCursor(p, k) {
    if (!p.bg) drawPlotBg(p);
    const g = p.c.getContext('2d');
    g.drawImage(p.bg, 0, 0);
    const dpr = window.devicePixelRatio || 1;
    const x = p.X(T[k]);
    g.strokeStyle = '#c0392b'; g.lineWidth = 1.5 * dpr;
    g.beginPath(); g.moveTo(x, 12 * dpr); g.lineTo(x, p.c.height); g.stroke();
    const v = p.data[k * n + p.j];
    g.fillStyle = '#c0392b'; g.beginPath(); g.arc(x, p.Y(v), 2.5 * dpr, 0, 7); g.fill();
    g.textAlign = 'right'; g.font = `${10 * dpr}px system-ui, sans-serif`;
    g.fillText(v.toFixed(4), p.c.width - 4 * dpr, 10 * dpr);
    g.textAlign = 'left';
  }

  // ---------------------------------------------------------------- state
  let frame = 0;
  const pairLabel = (k) => (k < 0 ? null : D.pairs[k]);
  function closestAt(c, k) {
    const p = CL[c].pair[k];
    if (p < 0) return null;
    const w = Array.from(CL[c].w.subarray(6 * k, 6 * k + 6));
    return { pair: D.pairs[p].label, a: D.pairs[p].a, b: D.pairs[p].b, distance: CL[c].dist[k], p1: w.slice(0, 3), p2: w.slice(3, 6) };
  }
  function setFrame(k) {
    frame = Math.max(0, Math.min(N - 1, k | 0));
    // link poses
    for (let l = 0; l < n; l++) {
      const o = (frame * n + l) * 7;
      linkGroups[l].position.set(LINKS[o], LINKS[o + 1], LINKS[o + 2]);
      linkGroups[l].quaternion.set(LINKS[o + 3], LINKS[o + 4], LINKS[o + 5], LINKS[o + 6]);
    }
    const sk = skelGeo.attributes.position.array;
    for (let l = 0; l < n; l++) {
      const o = (frame * n + l) * 7;
      const par = D.joints[l].parent;
      const po = par === null ? [0, 0, 0] : [LINKS[(frame * n + par) * 7], LINKS[(frame * n + par) * 7 + 1], LINKS[(frame * n + par) * 7 + 2]];
      sk.set([...po, LINKS[o], LINKS[o + 1], LINKS[o + 2]], 6 * l);
      jointDots[l].position.set(LINKS[o], LINKS[o + 1], LINKS[o + 2]);
    }
    skelGeo.attributes.position.needsUpdate = true;
    eeDot.position.set(EE[3 * frame], EE[3 * frame + 1], EE[3 * frame + 2]);
    // closest pairs
    const cl = { self: closestAt('self', frame), world: closestAt('world', frame) };
    for (const c of ['self', 'world']) {
      const v = pairViz[c], x = cl[c];
      v.line.visible = !!x; v.dots.forEach((d) => (d.visible = !!x));
      if (x) {
        v.line.geometry.attributes.position.array.set([...x.p1, ...x.p2]);
        v.line.geometry.attributes.position.needsUpdate = true;
        v.line.geometry.computeBoundingSphere();
        v.dots[0].position.set(...x.p1); v.dots[1].position.set(...x.p2);
      }
      // colour the two bodies of the closest self pair
    }
    bodyMeshes.forEach((ms, bi) => {
      const isSelf = cl.self && D.pairs[CL.self.pair[frame]].bodies.includes(bi);
      const isWorld = cl.world && D.pairs[CL.world.pair[frame]].bodies[0] === bi;
      for (const m of ms) {
        if (D.bodies[bi].obstacle) continue;
        m.material.color.set(isSelf ? 0xf1b0a8 : isWorld ? 0xa9c8f0 : D.bodies[bi].link === null ? 0x8e99ab : 0xb8c2d1);
      }
    });
    const t = T[frame], seg = SEG[frame];
    const q = Array.from(Q.subarray(frame * n, frame * n + n));
    const qd = Array.from(QD.subarray(frame * n, frame * n + n));
    if (!state.ready) state.load_ms = Math.round(performance.now());
    Object.assign(state, { ready: true, t, frame, frames: N, segment: seg === -2147483648 ? null : seg, phase: segName(seg), self: cl.self, world: cl.world, q, qd, hidden: hidden() });
    $('idexp-state').textContent = JSON.stringify(state);
    // heads-up display
    const hud = $('hud');
    hud.innerHTML = '';
    const line = (cls, text) => { const d = document.createElement('div'); d.className = cls; d.textContent = text; hud.appendChild(d); };
    line('t', `t = ${t.toFixed(3)} s  ${segName(seg)}`);
    const dist = (x, what) => (x ? `${what}: ${x.a} – ${x.b}  ${fmt(x.distance)} m` : `${what}: none within ${fmt(D.cap, 2)} m`);
    if (D.margin !== null) {
      line('row self', dist(cl.self, 'closest self pair'));
      line('row world', dist(cl.world, 'closest to floor / cell'));
    }
    $('scrub').value = String(Math.round((10000 * (t - t0)) / span));
    for (const p of plots) drawPlotCursor(p, frame);
    render();
  }
  function frameAt(t) {
    let lo = 0, hi = N - 1;
    while (lo < hi) { const m = (lo + hi) >> 1; if (T[m] < t) lo = m + 1; else hi = m; }
    if (lo > 0 && t - T[lo - 1] <= T[lo] - t) lo -= 1;
    return lo;
  }
  function setTime(t) { setFrame(frameAt(t)); }

  // ---------------------------------------------------------------- playback
  let playing = false, playT = t0, last = 0;
  function pause() { playing = false; $('play').textContent = '▶ play'; }
  function tick(now) {
    if (!playing) return;
    const dt = Math.min(0.1, (now - last) / 1000);
    last = now;
    playT += dt * parseFloat($('speed').value);
    if (playT >= t1) { playT = t1; pause(); }
    // the last frame at or before the playback time
    let k = frameAt(playT);
    if (T[k] > playT && k > 0) k -= 1;
    if (k !== frame) setFrame(k);
    if (playing) requestAnimationFrame(tick);
  }
  $('play').addEventListener('click', () => {
    if (playing) { pause(); return; }
    playing = true;
    playT = frame >= N - 1 ? t0 : T[frame];
    $('play').textContent = '❚❚ pause';
    last = performance.now();
    requestAnimationFrame(tick);
  });
  document.addEventListener('keydown', (e) => { if (e.code === 'Space' && e.target.tagName !== 'SELECT') { e.preventDefault(); $('play').click(); } });
  $('scrub').addEventListener('input', () => { pause(); setTime(t0 + (parseFloat($('scrub').value) / 10000) * span); });

  // URL hash: #t=12.5 (time), hide=robot,path (groups hidden), frame=k
  function hidden() { return Object.keys(groups).filter((k) => !groups[k].visible); }
  function applyHash() {
    const h = new URLSearchParams(location.hash.replace(/^#/, ''));
    const hide = (h.get('hide') || '').split(',').filter(Boolean);
    for (const k of Object.keys(groups)) {
      groups[k].visible = !hide.includes(k);
      const c = $('show-' + k);
      if (c) c.checked = groups[k].visible;
    }
    if (h.has('frame')) setFrame(parseInt(h.get('frame'), 10));
    else if (h.has('t')) setTime(parseFloat(h.get('t')));
    else setFrame(frame);
  }
  window.addEventListener('hashchange', applyHash);
  window.addEventListener('resize', () => { for (const p of plots) p.bg = null; resize(); setFrame(frame); });
  window.idexpSetTime = setTime;
  window.idexpSetFrame = setFrame;
  mark('panel');
  resize();
  mark('resize');
  applyHash();
  mark('ready');
  state.timing = marks;
  $('idexp-state').textContent = JSON.stringify(state);
}

main().catch(fail);
