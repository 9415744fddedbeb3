// oocfmt view: the page. It keeps the camera (world coordinates), sends it to the server over
// one WebSocket whenever it changes, and draws the frames that come back: JPEG while moving,
// PNG once the still view has refined. The server decides resolution, PoE and samples.
'use strict';

(() => {
  const token = new URLSearchParams(location.search).get('token') || '';
  const $ = (id) => document.getElementById(id);
  const canvas = $('frame');
  const ctx = canvas.getContext('2d');
  const view = $('view');
  const statusLine = $('status');

  // ---- vectors
  const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const mul = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const len = (a) => Math.sqrt(dot(a, a));
  const norm = (a) => { const l = len(a); return l > 0 ? mul(a, 1 / l) : a; };
  // `v` turned by `angle` radians about the unit axis `k` (Rodrigues).
  const rotate = (v, k, angle) => {
    const c = Math.cos(angle), s = Math.sin(angle);
    return add(add(mul(v, c), mul(cross(k, v), s)), mul(k, dot(k, v) * (1 - c)));
  };

  // ---- state
  let model = null;          // from the hello
  let cam = null;            // {eye, look_at, up, fov_y}
  let seq = 0;               // the number of the last camera sent
  let ws = null;
  let dirty = false;         // the camera changed since it was last sent
  let size = [1, 1];         // the image size asked for, device pixels
  let drawnOrder = 0, arrivals = 0;
  const sentAt = new Map();  // camera number -> when it was sent
  let latencyMs = null;
  const frameTimes = [];
  let last = null;           // {header, blob}
  const errors = [];
  const keys = new Set();
  let bookmarks = [];
  const picks = [];          // the answers to clicks, newest last
  let pickSeq = 0;
  // The last frames' arrivals, for benchmarks (tools/bench-view.py): when, the camera-to-frame
  // latency of a frame showing a camera first, and the header.
  const frameLog = [];
  let lastSentMs = null;
  // The section plane: off (''), along an axis ('x', 'y', 'z': the slider runs over the model's
  // box) or through a picked point ('pick': the slider moves it along the normal, half the
  // model's diagonal either way); `flip` keeps the other side.
  const section = { mode: '', pos: 500, flip: false, at: null };
  let sectionDirty = false;
  let sectionSent = null;

  // Exposed for the browser tests and for people poking at the page.
  window.oocfmt = {
    get camera() { return cam && JSON.parse(JSON.stringify(cam)); },
    get frames() { return arrivals; },
    get last() { return last && last.header; },
    get errors() { return errors.slice(); },
    get bookmarks() { return bookmarks.slice(); },
    get history() { return frameLog.slice(); },
    get picks() { return picks.slice(); },
    get lastSentMs() { return lastSentMs; },
    get tree() {
      return {
        hidden: [...tree.hidden], isolated: tree.isolated, picked: tree.picked,
        rows: tree.rows.size, shown: [...tree.rows.values()].filter((r) => r.el.isConnected && !hiddenRow(r)).length,
      };
    },
    get section() { return sectionSent && JSON.parse(JSON.stringify(sectionSent)); },
    send: (obj) => ws && ws.readyState === 1 && ws.send(typeof obj === 'string' ? obj : JSON.stringify(obj)),
    pathJson: () => pathJson(),
    onScreen: (p) => onScreen(p),
  };

  const notice = (text) => {
    const n = $('notice');
    n.textContent = text;
    n.hidden = !text;
  };

  // ---- the camera
  const diagonal = () => (model ? len(sub(model.bounds_max, model.bounds_min)) : 1) || 1;
  const centre = () => (model ? mul(add(model.bounds_min, model.bounds_max), 0.5) : [0, 0, 0]);

  // The frame of the camera: unit forward, right and up, and the size of a pixel at distance 1.
  function basis(c) {
    const f = norm(sub(c.look_at, c.eye));
    let r = cross(f, c.up);
    if (len(r) < 1e-12) r = cross(f, Math.abs(f[1]) < 0.9 ? [0, 1, 0] : [1, 0, 0]);
    r = norm(r);
    const u = cross(r, f);
    const pixel = 2 * Math.tan((c.fov_y * Math.PI) / 360) / size[1];
    return { f, r, u, pixel };
  }

  // Looks along `forward` at the whole model, from where its bounding sphere just fits.
  function fit(forward, up) {
    const c = centre();
    const radius = diagonal() / 2;
    const fovY = ((cam ? cam.fov_y : 45) * Math.PI) / 180;
    const fovX = 2 * Math.atan(Math.tan(fovY / 2) * (size[0] / size[1]));
    const dist = (radius / Math.sin(Math.min(fovX, fovY) / 2)) * 1.02;
    const f = norm(forward);
    cam = { eye: sub(c, mul(f, dist)), look_at: c, up: up || (cam ? cam.up : [0, 1, 0]), fov_y: cam ? cam.fov_y : 45 };
    changed();
  }

  const VIEWS = {
    front: { f: [0, 0, -1], up: [0, 1, 0] },
    top: { f: [0, -1, 0], up: [0, 0, -1] },
    side: { f: [-1, 0, 0], up: [0, 1, 0] },
    iso: { f: [-1, -1, -1], up: [0, 1, 0] },
  };
  const standard = (name) => fit(VIEWS[name].f, VIEWS[name].up);
  const fitAll = () => fit(cam ? sub(cam.look_at, cam.eye) : VIEWS.iso.f, cam ? cam.up : [0, 1, 0]);

  function orbit(dx, dy) {
    const up = norm(cam.up);
    let off = sub(cam.eye, cam.look_at);
    off = rotate(off, up, -dx * 0.006);
    const right = norm(cross(mul(off, -1), up));
    const turned = rotate(off, right, -dy * 0.006);
    // Never over the pole: keep the eye off the up axis.
    const cos = dot(norm(turned), up);
    if (Math.abs(cos) < 0.995) off = turned;
    cam.eye = add(cam.look_at, off);
    changed();
  }

  function look(dx, dy) {
    const up = norm(cam.up);
    let dir = sub(cam.look_at, cam.eye);
    dir = rotate(dir, up, -dx * 0.004);
    const right = norm(cross(dir, up));
    const turned = rotate(dir, right, -dy * 0.004);
    if (Math.abs(dot(norm(turned), up)) < 0.995) dir = turned;
    cam.look_at = add(cam.eye, dir);
    changed();
  }

  // Moves the view so that the point under the cursor follows it, at the orbit distance.
  function pan(dx, dy) {
    const b = basis(cam);
    const s = len(sub(cam.look_at, cam.eye)) * b.pixel * (window.devicePixelRatio || 1);
    const move = add(mul(b.r, -dx * s), mul(b.u, dy * s));
    cam.eye = add(cam.eye, move);
    cam.look_at = add(cam.look_at, move);
    changed();
  }

  // Zooms towards the point under (px, py), CSS pixels in the canvas: the eye moves along the
  // ray through it and the orbit distance shrinks by the same factor.
  function zoom(px, py, amount) {
    const b = basis(cam);
    const dpr = window.devicePixelRatio || 1;
    const sx = (px * dpr - size[0] / 2) * b.pixel;
    const sy = (size[1] / 2 - py * dpr) * b.pixel;
    const dir = norm(add(b.f, add(mul(b.r, sx), mul(b.u, sy))));
    const dist = len(sub(cam.look_at, cam.eye));
    const k = Math.exp(-amount);
    const step = dist * (1 - k);
    cam.eye = add(cam.eye, mul(dir, step));
    cam.look_at = add(cam.eye, mul(b.f, Math.max(dist * k, diagonal() * 1e-6)));
    changed();
  }

  function fly(dt) {
    if (!cam || keys.size === 0) return;
    const b = basis(cam);
    const speed = diagonal() * 0.25 * (keys.has('Shift') ? 4 : 1) * dt;
    let move = [0, 0, 0];
    if (keys.has('w')) move = add(move, b.f);
    if (keys.has('s')) move = sub(move, b.f);
    if (keys.has('d')) move = add(move, b.r);
    if (keys.has('a')) move = sub(move, b.r);
    if (keys.has('e')) move = add(move, norm(cam.up));
    if (keys.has('q')) move = sub(move, norm(cam.up));
    const turn = 90 * dt;
    if (keys.has('ArrowLeft')) look(-turn * 2.5, 0);
    if (keys.has('ArrowRight')) look(turn * 2.5, 0);
    if (keys.has('ArrowUp')) look(0, -turn * 2.5);
    if (keys.has('ArrowDown')) look(0, turn * 2.5);
    if (len(move) > 0) {
      const m = mul(norm(move), speed);
      cam.eye = add(cam.eye, m);
      cam.look_at = add(cam.look_at, m);
      changed();
    }
  }

  // ---- the camera in the address
  const fmt = (v) => v.map(String).join(',');
  function hashOf(c) {
    return `#eye=${fmt(c.eye)}&look=${fmt(c.look_at)}&up=${fmt(c.up)}&fov=${c.fov_y}`;
  }
  function fromHash(hash) {
    const p = new URLSearchParams(hash.replace(/^#/, ''));
    const vec = (k) => {
      const v = (p.get(k) || '').split(',').map(Number);
      return v.length === 3 && v.every(Number.isFinite) ? v : null;
    };
    const eye = vec('eye'), at = vec('look'), up = vec('up') || [0, 1, 0];
    const fov = Number(p.get('fov') || 45);
    if (!eye || !at || !Number.isFinite(fov)) return null;
    return { eye, look_at: at, up, fov_y: fov };
  }
  let hashTimer = null;
  function keepHash() {
    if (hashTimer) return;
    hashTimer = setTimeout(() => {
      hashTimer = null;
      if (cam) history.replaceState(null, '', hashOf(cam));
    }, 200);
  }

  // ---- sending
  function changed() {
    dirty = true;
    keepHash();
    $('fov').value = String(Math.round(cam.fov_y));
    $('fov-value').textContent = `${Math.round(cam.fov_y)}°`;
  }

  function resize() {
    const dpr = window.devicePixelRatio || 1;
    let w = Math.max(1, Math.round(view.clientWidth * dpr));
    let h = Math.max(1, Math.round(view.clientHeight * dpr));
    const max = model ? model.max_pixels : 1 << 22;
    if (w * h > max) {
      const s = Math.sqrt(max / (w * h));
      w = Math.max(1, Math.floor(w * s));
      h = Math.max(1, Math.floor(h * s));
    }
    if (w !== size[0] || h !== size[1]) {
      size = [w, h];
      canvas.width = w;
      canvas.height = h;
      if (last && last.bitmap) draw(last.bitmap);
      dirty = true;
    }
  }

  function sendCamera() {
    if (!cam || !ws || ws.readyState !== 1) return;
    seq += 1;
    lastSentMs = performance.now();
    sentAt.set(seq, lastSentMs);
    if (sentAt.size > 256) sentAt.delete(sentAt.keys().next().value);
    ws.send(JSON.stringify({ type: 'camera', seq, eye: cam.eye, look_at: cam.look_at, up: cam.up, fov_y: cam.fov_y, width: size[0], height: size[1] }));
    dirty = false;
  }

  // The plane the section control describes, world coordinates: keeps normal · p >= offset.
  function sectionPlane() {
    if (!model || !section.mode) return null;
    const t = section.pos / 1000;
    let normal, offset;
    if (section.mode === 'pick') {
      if (!section.at) return null;
      // The picked normal faces the eye: keeping the side behind it cuts the surface away where
      // it was clicked and opens the model there; a hair past the point, so the picked
      // surface itself does not flicker on the plane.
      normal = mul(section.at.normal, -1);
      offset = dot(normal, section.at.point) + (t - 0.5) * diagonal() + 1e-5 * diagonal();
    } else {
      const k = 'xyz'.indexOf(section.mode);
      normal = [0, 0, 0];
      normal[k] = 1;
      offset = model.bounds_min[k] + t * (model.bounds_max[k] - model.bounds_min[k]);
    }
    if (section.flip) { normal = mul(normal, -1); offset = -offset; }
    return { normal, offset };
  }

  function showSection() {
    const p = sectionPlane();
    $('section-pos').disabled = !p;
    $('section-flip').disabled = !p;
    let text = '';
    if (p && section.mode !== 'pick') {
      const k = 'xyz'.indexOf(section.mode);
      text = `${section.mode} ${p.normal[k] > 0 ? '≥' : '≤'} ${num(p.normal[k] * p.offset)}`;
    } else if (p) {
      text = `through ${vec(section.at.point)}`;
    }
    $('section-value').textContent = text;
  }

  function sendSection() {
    if (!ws || ws.readyState !== 1) return;
    sectionSent = sectionPlane();
    sectionDirty = false;
    ws.send(JSON.stringify({ type: 'section', plane: sectionSent }));
  }

  function setSectionMode(mode) {
    if (mode === 'pick') {
      const p = picks.slice().reverse().find((m) => m.hit);
      if (!p) {
        notice('Pick a point first: the section goes through it, along its normal.');
        setTimeout(() => notice(''), 4000);
        mode = '';
      } else {
        section.at = { point: p.hit.point, normal: p.hit.normal };
      }
    }
    // A new plane starts in the middle, keeping the side its normal points to.
    section.mode = mode;
    section.pos = 500;
    section.flip = false;
    $('section-axis').value = mode;
    $('section-pos').value = '500';
    sectionDirty = true;
    showSection();
  }

  function sendQuality() {
    const poe = Number($('poe').value), spp = Math.round(Number($('spp').value));
    if (ws && ws.readyState === 1) ws.send(JSON.stringify({ type: 'quality', poe, spp }));
  }

  // ---- the model tree (files with parts): a level at a time, children asked for on expand
  const tree = { hidden: new Set(), isolated: null, rows: new Map(), seq: 0, picked: null, opening: [] };
  const hiddenRow = (r) => { for (let e = r.el.parentElement; e && e.id !== 'tree-rows'; e = e.parentElement) if (e.hidden) return true; return false; };

  function askChildren(parent, offset) {
    if (!ws || ws.readyState !== 1) return;
    tree.seq += 1;
    ws.send(JSON.stringify({ type: 'part_children', seq: tree.seq, parent, offset }));
  }

  function partRow(c) {
    const el = document.createElement('div');
    el.className = 'part';
    const line = document.createElement('div');
    line.className = 'line';
    line.dataset.id = String(c.id);
    const toggle = document.createElement('span');
    toggle.className = 'toggle';
    toggle.textContent = c.children > 0 ? '▸' : '';
    const show = document.createElement('input');
    show.type = 'checkbox';
    show.checked = !tree.hidden.has(c.id);
    show.title = 'Shown (unticked: hidden, with what is under it)';
    const name = document.createElement('span');
    name.className = 'name';
    name.textContent = c.name;
    name.title = `part ${c.id}: ${c.name}`;
    const tris = document.createElement('span');
    tris.className = 'tris';
    tris.textContent = c.triangles.toLocaleString('en');
    const iso = document.createElement('button');
    iso.textContent = 'isolate';
    iso.title = 'Show only this part and what is under it (again: show all)';
    line.append(toggle, show, name, tris, iso);
    const kids = document.createElement('div');
    kids.className = 'kids';
    kids.hidden = true;
    el.append(line, kids);
    const r = { el, line, kids, toggle, show, item: c, open: false, loaded: false };
    tree.rows.set(c.id, r);
    toggle.addEventListener('click', () => expand(c.id, !r.open));
    name.addEventListener('dblclick', () => expand(c.id, !r.open));
    show.addEventListener('change', () => {
      if (show.checked) tree.hidden.delete(c.id); else tree.hidden.add(c.id);
      sendParts();
    });
    iso.addEventListener('click', () => {
      tree.isolated = tree.isolated === c.id ? null : c.id;
      sendParts();
    });
    if (tree.isolated === c.id) line.classList.add('isolated');
    return el;
  }

  function expand(id, open) {
    const r = tree.rows.get(id);
    if (!r || r.item.children === 0) return;
    if (open && !r.loaded) { r.loaded = true; askChildren(id, 0); }
    r.open = open;
    r.kids.hidden = !open;
    r.toggle.textContent = open ? '▾' : '▸';
  }

  function onChildren(m) {
    const box = m.parent === null ? $('tree-rows') : tree.rows.get(m.parent) && tree.rows.get(m.parent).kids;
    if (!box) return;
    const more = box.querySelector(':scope > .more');
    if (more) more.remove();
    for (const c of m.children) box.appendChild(partRow(c));
    const next = m.offset + m.children.length;
    if (next < m.total) {
      const b = document.createElement('button');
      b.className = 'more';
      b.textContent = `${m.total - next} more…`;
      b.addEventListener('click', () => { b.remove(); askChildren(m.parent, next); });
      box.appendChild(b);
    }
    openTo();
  }

  // Opens the tree down the picked part's lineage, as its levels arrive, and marks the part.
  function openTo() {
    while (tree.opening.length) {
      const id = tree.opening[0];
      const r = tree.rows.get(id);
      if (!r) return;
      tree.opening.shift();
      if (tree.opening.length) {
        expand(id, true);
      } else {
        for (const p of document.querySelectorAll('#tree .line.picked')) p.classList.remove('picked');
        r.line.classList.add('picked');
        r.line.scrollIntoView({ block: 'nearest' });
      }
    }
  }

  function sendParts() {
    if (!ws || ws.readyState !== 1) return;
    const isolate = tree.isolated === null ? [] : [tree.isolated];
    ws.send(JSON.stringify({ type: 'parts', hide: [...tree.hidden], isolate }));
    for (const r of tree.rows.values()) {
      r.line.classList.toggle('isolated', tree.isolated === r.item.id);
      r.show.checked = !tree.hidden.has(r.item.id);
    }
    const n = tree.hidden.size;
    $('tree-state').textContent = (n ? `${n} hidden` : '') + (tree.isolated !== null ? `${n ? ' · ' : ''}isolated` : '');
  }

  // ---- receiving
  function onText(m) {
    if (m.type === 'hello') {
      model = { ...m.model, max_pixels: m.max_pixels };
      $('title').textContent = `${m.model.name} · ${m.model.triangles.toLocaleString('en')} triangles`;
      document.title = `${m.model.name} · oocfmt view`;
      $('poe').value = String(m.quality.poe);
      $('spp').value = String(m.quality.spp);
      loadBookmarks();
      if (m.model.parts > 0) {
        $('tree-toggle').hidden = false;
        $('tree').hidden = false;
        askChildren(null, 0);
      }
      resize();
      cam = fromHash(location.hash);
      if (cam) changed(); else standard('iso');
    } else if (m.type === 'part_children') {
      onChildren(m);
    } else if (m.type === 'pick') {
      if (m.lineage && m.lineage.length) {
        tree.picked = m.lineage[m.lineage.length - 1];
        tree.opening = m.lineage.slice();
        openTo();
      }
      if (m.hit) snap(m);
      picks.push(m);
      if (picks.length > 100) picks.shift();
      showPick();
      if (last && last.bitmap) draw(last.bitmap);
    } else if (m.type === 'error') {
      errors.push(m.message);
      notice(m.message);
      setTimeout(() => notice(''), 4000);
    }
  }

  function onFrame(buf) {
    const bytes = new Uint8Array(buf);
    if (bytes.length < 8 || String.fromCharCode(...bytes.subarray(0, 4)) !== 'OVF1') return;
    const hlen = new DataView(buf).getUint32(4, true);
    const header = JSON.parse(new TextDecoder().decode(bytes.subarray(8, 8 + hlen)));
    const blob = new Blob([bytes.subarray(8 + hlen)], { type: `image/${header.format}` });
    const order = ++arrivals;
    const now = performance.now();
    frameTimes.push(now);
    while (frameTimes.length && frameTimes[0] < now - 1000) frameTimes.shift();
    let latency = null;
    if (sentAt.has(header.seq)) {
      latency = latencyMs = now - sentAt.get(header.seq);
      for (const k of [...sentAt.keys()]) if (k <= header.seq) sentAt.delete(k);
    }
    frameLog.push({ at: now, latency, header });
    if (frameLog.length > 4000) frameLog.shift();
    createImageBitmap(blob).then((bitmap) => {
      if (order < drawnOrder) return;
      drawnOrder = order;
      last = { header, blob, bitmap };
      draw(bitmap);
      status(header);
    });
  }

  // A click asks what is under the cursor; the answer shows its distance, point, normal and
  // part, and the distance from the point picked before (a measurement).
  function sendPick(px, py) {
    if (!ws || ws.readyState !== 1) return;
    const x = Math.min(size[0] - 1, Math.max(0, Math.floor((px * canvas.width) / canvas.clientWidth)));
    const y = Math.min(size[1] - 1, Math.max(0, Math.floor((py * canvas.height) / canvas.clientHeight)));
    pickSeq += 1;
    ws.send(JSON.stringify({ type: 'pick', seq: pickSeq, x, y }));
  }

  const num = (v) => String(parseFloat(Number(v).toPrecision(6)));
  const vec = (v) => `(${v.map(num).join(', ')})`;
  function showPick() {
    const el = $('pick');
    const m = picks[picks.length - 1];
    el.hidden = false;
    if (!m.hit) {
      el.textContent = `pick ${m.x},${m.y}: nothing there (background)`;
      return;
    }
    const h = m.hit;
    let text = `pick ${m.x},${m.y}: distance ${num(h.distance)} · point ${vec(h.point)} · normal ${vec(h.normal)}`;
    if (h.part_name !== null && h.part_name !== undefined) text += ` · part ${h.part_path || h.part_name}`;
    if (h.lod) text += ' · LOD entry (PoE > 0)';
    if (m.snapped) text += ` · snapped to the vertex ${vec(m.measured)}`;
    const before = picks.slice(0, -1).reverse().find((p) => p.hit);
    if (before) text += ` · from the pick before: ${num(len(sub(m.measured, before.measured)))}`;
    el.textContent = text;
  }

  function draw(bitmap) {
    ctx.imageSmoothingEnabled = true;
    ctx.drawImage(bitmap, 0, 0, canvas.width, canvas.height);
    marks();
  }

  // The last two picked points over the frame, joined by the measured line.
  // Where world point `p` is in the image, in image pixels; null behind the eye.
  function onScreen(p) {
    if (!cam) return null;
    const b = basis(cam);
    const d = sub(p, cam.eye);
    const z = dot(d, b.f);
    if (z <= 0) return null;
    return [dot(d, b.r) / (z * b.pixel) + size[0] / 2, size[1] / 2 - dot(d, b.u) / (z * b.pixel)];
  }

  // A measure snaps to the hit triangle's nearest corner when it is within SNAP_PX screen
  // pixels of the click (full detail only: a LOD entry has no corners).
  const SNAP_PX = 6;
  function snap(m) {
    m.measured = m.hit.point;
    m.snapped = false;
    if (!m.hit.corners) return;
    const scale = canvas.clientWidth > 0 ? canvas.width / canvas.clientWidth : 1;
    let best = null;
    for (const c of m.hit.corners) {
      const s = onScreen(c);
      if (!s) continue;
      const d = Math.hypot(s[0] - (m.x + 0.5), s[1] - (m.y + 0.5)) / scale;
      if (d <= SNAP_PX && (!best || d < best.d)) best = { d, c };
    }
    if (best) { m.measured = best.c; m.snapped = true; }
  }

  function marks() {
    if (!cam) return;
    const pts = picks.filter((p) => p.hit).slice(-2).map((p) => onScreen(p.measured || p.hit.point)).filter((p) => p);
    ctx.save();
    ctx.strokeStyle = '#ff9a3c';
    ctx.lineWidth = 2;
    if (pts.length === 2) {
      ctx.beginPath();
      ctx.moveTo(pts[0][0], pts[0][1]);
      ctx.lineTo(pts[1][0], pts[1][1]);
      ctx.stroke();
    }
    for (const [x, y] of pts) {
      ctx.beginPath();
      ctx.arc(x, y, 5, 0, 2 * Math.PI);
      ctx.stroke();
    }
    ctx.restore();
  }

  function status(h) {
    const f = h.figures;
    const parts = [
      `frame ${f.ms.toFixed(1)} ms`,
      `${frameTimes.length} fps`,
      `${f.width}×${f.height}`,
      `PoE ${f.poe}`,
      `${f.samples}/${f.spp} spp`,
      f.stage + (f.last ? ' (final)' : ''),
      `full detail ${(100 * f.full_detail).toFixed(1)}%`,
      `cache ${f.cache_mib.toFixed(1)} / ${f.cache_budget_mib.toFixed(0)} MiB`,
      `${f.blocks_pending} pending`,
      `${f.blocks_loaded_per_s.toFixed(0)} loaded/s`,
      latencyMs === null ? null : `latency ${latencyMs.toFixed(0)} ms`,
      `${h.format} ${(h.bytes / 1024).toFixed(0)} KiB`,
    ];
    statusLine.textContent = parts.filter((p) => p !== null).join(' · ');
  }

  // ---- the mouse, touch and keys
  // Pointer Events, one path for the mouse, a pen and fingers. One pointer drags: orbit (pan
  // with the right button or shift, look around with ctrl or alt). Two fingers pinch: the change
  // in their distance zooms to their midpoint, the midpoint's movement pans. A gesture that
  // ever had two pointers does not pick when it ends.
  const pointers = new Map();
  let pinch = null;          // the two first pointers' distance and midpoint, CSS pixels
  let multi = false;
  const pair = () => {
    const [a, b] = [...pointers.values()];
    return { d: Math.hypot(a.x - b.x, a.y - b.y), x: (a.x + b.x) / 2, y: (a.y + b.y) / 2 };
  };
  canvas.addEventListener('contextmenu', (e) => e.preventDefault());
  canvas.addEventListener('pointerdown', (e) => {
    view.focus();
    canvas.setPointerCapture(e.pointerId);
    if (pointers.size === 0) multi = false;
    pointers.set(e.pointerId, { x: e.offsetX, y: e.offsetY, x0: e.offsetX, y0: e.offsetY, button: e.button, drag: false });
    canvas.classList.add('dragging');
    if (pointers.size >= 2) {
      multi = true;
      pinch = pair();
    }
  });
  canvas.addEventListener('pointermove', (e) => {
    const p = pointers.get(e.pointerId);
    if (!p || !cam) return;
    if (pointers.size >= 2) {
      // Applied once per animation frame (`pinchStep`): fingers that move together arrive
      // as one event each, and the midpoint must not wander between them.
      p.x = e.offsetX;
      p.y = e.offsetY;
      return;
    }
    // A drag starts past a few pixels, so that a click or a tap picks without turning the view.
    if (!p.drag && Math.hypot(e.offsetX - p.x0, e.offsetY - p.y0) < 4) return;
    p.drag = true;
    const dx = e.offsetX - p.x, dy = e.offsetY - p.y;
    p.x = e.offsetX;
    p.y = e.offsetY;
    if (p.button === 2 || e.shiftKey || p.button === 1) pan(dx, dy);
    else if (e.ctrlKey || e.altKey) look(dx, dy);
    else orbit(dx, dy);
  });
  // The pinch since the last animation frame: the distance's ratio zooms to the midpoint, the
  // midpoint's movement pans.
  function pinchStep() {
    if (!pinch || !cam || pointers.size < 2) return;
    const now = pair();
    if (pinch.d > 0 && now.d > 0 && now.d !== pinch.d) zoom(now.x, now.y, Math.log(now.d / pinch.d));
    if (now.x !== pinch.x || now.y !== pinch.y) pan(now.x - pinch.x, now.y - pinch.y);
    pinch = now;
  }
  const release = (e) => {
    pinchStep();
    const p = pointers.get(e.pointerId);
    if (p && !p.drag && !multi && p.button === 0 && pointers.size === 1 && e.type === 'pointerup' && cam) sendPick(p.x0, p.y0);
    pointers.delete(e.pointerId);
    if (pointers.size < 2) pinch = null;
    // The finger left after a pinch orbits on from where it is, without a jump.
    if (pointers.size === 1) for (const q of pointers.values()) q.drag = true;
    if (pointers.size >= 2) pinch = pair();
    if (pointers.size === 0) canvas.classList.remove('dragging');
  };
  canvas.addEventListener('pointerup', release);
  canvas.addEventListener('pointercancel', release);
  canvas.addEventListener('wheel', (e) => {
    e.preventDefault();
    if (!cam) return;
    // Lines and pages as pixels; a trackpad pinch comes as a wheel with ctrl, finer.
    const unit = e.deltaMode === 1 ? 16 : e.deltaMode === 2 ? 400 : 1;
    const amount = -e.deltaY * unit * (e.ctrlKey ? 0.01 : 0.0015);
    zoom(e.offsetX, e.offsetY, Math.max(-1, Math.min(1, amount)));
  }, { passive: false });

  const FLY = new Set(['w', 'a', 's', 'd', 'q', 'e', 'ArrowLeft', 'ArrowRight', 'ArrowUp', 'ArrowDown', 'Shift']);
  const keyName = (e) => (e.key.length === 1 ? e.key.toLowerCase() : e.key);
  window.addEventListener('keydown', (e) => {
    if (e.target instanceof HTMLInputElement) return;
    const k = keyName(e);
    if (FLY.has(k)) {
      keys.add(k);
      e.preventDefault();
      return;
    }
    if (!cam) return;
    if (k === 'f') fitAll();
    else if (k === '1') standard('front');
    else if (k === '2') standard('top');
    else if (k === '3') standard('side');
    else if (k === '4') standard('iso');
    else if (k === 'b') addBookmark();
  });
  window.addEventListener('keyup', (e) => {
    keys.delete(keyName(e));
    if (e.key === 'Shift') keys.delete('Shift');
  });
  window.addEventListener('blur', () => keys.clear());

  // ---- the bar
  $('fit').addEventListener('click', () => cam && fitAll());
  for (const b of document.querySelectorAll('button.std')) {
    b.addEventListener('click', () => cam && standard(b.dataset.view));
  }
  $('fov').addEventListener('input', (e) => {
    if (!cam) return;
    cam.fov_y = Number(e.target.value);
    changed();
  });
  $('poe').addEventListener('change', sendQuality);
  $('spp').addEventListener('change', sendQuality);
  $('section-axis').addEventListener('change', (e) => setSectionMode(e.target.value));
  $('section-pos').addEventListener('input', (e) => {
    section.pos = Number(e.target.value);
    sectionDirty = true;
    showSection();
  });
  $('section-flip').addEventListener('click', () => {
    section.flip = !section.flip;
    sectionDirty = true;
    showSection();
  });
  $('tree-toggle').addEventListener('click', () => { $('tree').hidden = !$('tree').hidden; });
  $('tree-all').addEventListener('click', () => {
    tree.hidden.clear();
    tree.isolated = null;
    sendParts();
  });
  $('help-toggle').addEventListener('click', () => { $('help').hidden = !$('help').hidden; });

  function download(blob, name) {
    const a = document.createElement('a');
    a.href = URL.createObjectURL(blob);
    a.download = name;
    document.body.appendChild(a);
    a.click();
    a.remove();
    setTimeout(() => URL.revokeObjectURL(a.href), 1000);
  }
  $('shot').addEventListener('click', () => {
    if (!last) return;
    const ext = last.header.format === 'png' ? 'png' : 'jpg';
    download(last.blob, `${(model && model.name) || 'view'}-${last.header.figures.width}x${last.header.figures.height}.${ext}`);
  });

  // Bookmarks: cameras in world coordinates, kept per model in this browser, saved as the
  // list form of a `render --path` file (one frame per bookmark).
  const storeKey = () => `oocfmt-bookmarks:${model ? model.name : ''}`;
  function loadBookmarks() {
    try {
      const v = JSON.parse(localStorage.getItem(storeKey()) || '[]');
      bookmarks = Array.isArray(v) ? v : [];
    } catch (_) {
      bookmarks = [];
    }
    $('marks').textContent = String(bookmarks.length);
  }
  function addBookmark() {
    bookmarks.push({ eye: cam.eye.slice(), look_at: cam.look_at.slice(), up: cam.up.slice(), fov_y: cam.fov_y });
    try { localStorage.setItem(storeKey(), JSON.stringify(bookmarks)); } catch (_) { /* private mode */ }
    $('marks').textContent = String(bookmarks.length);
  }
  const pathJson = () => JSON.stringify(bookmarks, null, 1);
  $('mark').addEventListener('click', () => cam && addBookmark());
  $('path').addEventListener('click', (e) => {
    if (e.shiftKey) {
      bookmarks = [];
      try { localStorage.removeItem(storeKey()); } catch (_) { /* private mode */ }
      $('marks').textContent = '0';
      return;
    }
    if (bookmarks.length) download(new Blob([pathJson()], { type: 'application/json' }), 'path.json');
  });

  window.addEventListener('hashchange', () => {
    const c = fromHash(location.hash);
    if (c && (!cam || hashOf(c) !== hashOf(cam))) {
      cam = c;
      changed();
    }
  });
  window.addEventListener('resize', resize);

  // ---- the loop: fly keys, then at most one camera per animation frame
  let then = performance.now();
  function tick(now) {
    const dt = Math.min(0.1, (now - then) / 1000);
    then = now;
    fly(dt);
    pinchStep();
    resize();
    if (dirty) sendCamera();
    if (sectionDirty) sendSection();
    requestAnimationFrame(tick);
  }

  function connect() {
    const proto = location.protocol === 'https:' ? 'wss:' : 'ws:';
    ws = new WebSocket(`${proto}//${location.host}/ws?token=${encodeURIComponent(token)}`);
    ws.binaryType = 'arraybuffer';
    ws.onopen = () => { statusLine.textContent = 'connected, waiting for the first frame…'; };
    ws.onmessage = (ev) => (typeof ev.data === 'string' ? onText(JSON.parse(ev.data)) : onFrame(ev.data));
    ws.onclose = () => {
      notice('Disconnected: the server stopped, or refused this page. Open the URL `oocfmt view` printed.');
      statusLine.textContent = 'disconnected';
    };
  }

  connect();
  requestAnimationFrame(tick);
})();
