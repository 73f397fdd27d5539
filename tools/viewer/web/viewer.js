// anchormap live map: keeps the viewer's state (a "full" message, then "delta" messages
// over a WebSocket; docs/DAEMONS.md describes them) and draws it on a canvas. Sends the
// server nothing but a hello. The page's own state for tests: window.anchormapViewer.state()
// and the JSON in <pre id="viewer-state">.
'use strict';

(function () {
  // ---- state ------------------------------------------------------------------------
  const model = {
    seq: -1, restarts: 0, mapUpdate: -1, mapUtime: 0, wallUtime: 0,
    trajectories: new Map(),  // key -> {robot, id, anchored, anchor, poses: [x,y,t,...]}
    links: [],                // [keyA, indexA, keyB, indexB, kind]
    tiles: new Map(),         // "x,y" -> {x, y, w, h, res, update, image (canvas)}
    covariances: null, status: null,
  };
  const stats = { fulls: 0, deltas: 0, messages: 0, bytes: 0, skipped: 0, frames: 0,
                  lastFrameMs: 0, maxFrameMs: 0, totalFrameMs: 0, connected: false };

  function applyMessage(m) {
    if (m.type === 'full') {
      model.trajectories.clear();
      model.links = [];
      model.tiles.clear();
      stats.fulls++;
    } else if (m.type === 'delta') {
      if (m.seq <= model.seq) { stats.skipped++; return; }  // already in a full state
      stats.deltas++;
    } else {
      return;
    }
    model.seq = m.seq;
    model.restarts = m.restarts;
    model.mapUpdate = m.map_update;
    model.mapUtime = m.map_utime;
    model.wallUtime = m.wall_utime;
    for (const key of m.removed || []) model.trajectories.delete(key);
    for (const t of m.trajectories || []) {
      let mine = model.trajectories.get(t.key);
      if (!mine) {
        mine = { robot: t.robot, id: t.id, poses: [] };
        model.trajectories.set(t.key, mine);
      }
      mine.anchored = t.anchored;
      mine.anchor = t.anchor;
      mine.poses.length = Math.min(mine.poses.length, 3 * t.from);
      for (const v of t.poses) mine.poses.push(v);
      mine.poses.length = 3 * t.num_poses;
    }
    if (m.encounters) {
      model.links.length = Math.min(model.links.length, m.encounters.from);
      for (const l of m.encounters.links) model.links.push(l);
    }
    if (m.clear_tiles) model.tiles.clear();
    for (const key of m.removed_tiles || []) model.tiles.delete(key);
    for (const t of m.tiles || []) model.tiles.set(t.x + ',' + t.y, makeTile(t));
    if ('covariances' in m) model.covariances = m.covariances;
    if ('status' in m) model.status = m.status;
  }

  // A tile's cells as a small canvas: free white, occupied dark, unknown transparent.
  function makeTile(t) {
    const bytes = atob(t.cells);
    const image = document.createElement('canvas');
    image.width = t.w;
    image.height = t.h;
    const context = image.getContext('2d');
    const data = context.createImageData(t.w, t.h);
    for (let row = 0; row < t.h; row++) {
      const out = (t.h - 1 - row) * t.w;  // row 0 is at the bottom
      for (let col = 0; col < t.w; col++) {
        const v = bytes.charCodeAt(row * t.w + col);
        const o = 4 * (out + col);
        if (v > 127) { data.data[o + 3] = 0; continue; }  // -1: unknown
        const grey = Math.round(255 - 2.3 * v);
        data.data[o] = grey; data.data[o + 1] = grey; data.data[o + 2] = grey; data.data[o + 3] = 255;
      }
    }
    context.putImageData(data, 0, 0);
    return { x: t.x, y: t.y, w: t.w, h: t.h, res: t.res, update: t.update, image: image };
  }

  // ---- colours: the same as anchormap-render's (tools/render/colors.cc) ----------------
  const kPalette = [[31, 119, 180], [255, 127, 14], [44, 160, 44], [214, 39, 40],
                    [148, 103, 189], [140, 86, 75], [227, 119, 194], [188, 189, 34],
                    [23, 190, 207], [31, 60, 110]];
  function hsv(h, s, v) {
    const c = v * s, hh = (h % 360) / 60, x = c * (1 - Math.abs(hh % 2 - 1)), m = v - c;
    const [r, g, b] = hh < 1 ? [c, x, 0] : hh < 2 ? [x, c, 0] : hh < 3 ? [0, c, x]
                    : hh < 4 ? [0, x, c] : hh < 5 ? [x, 0, c] : [c, 0, x];
    return [r, g, b].map((u) => Math.round(Math.min(1, Math.max(0, u + m)) * 255));
  }
  function colorOf(index) {
    if (index < kPalette.length) return kPalette[index];
    return hsv(index * 137.50776, 0.85, 0.55 + 0.3 * (Math.floor(index / 3) % 2));
  }
  function naturalParts(name) {
    const match = /^(.*?)(\d{1,9})$/.exec(name);
    return match ? [match[1], Number(match[2])] : [name, -1];
  }
  function compareKeys(a, b) {  // natural robot order (R2 < R10), then id
    const pa = naturalParts(a.robot), pb = naturalParts(b.robot);
    if (pa[0] !== pb[0]) return pa[0] < pb[0] ? -1 : 1;
    if (pa[1] !== pb[1]) return pa[1] - pb[1];
    if (a.robot !== b.robot) return a.robot < b.robot ? -1 : 1;
    return a.id - b.id;
  }
  function sortedTrajectories() {
    const list = [...model.trajectories.entries()].map(([key, t]) => Object.assign({ key: key }, t));
    list.sort(compareKeys);
    list.forEach((t, i) => { t.color = colorOf(i); });
    return list;
  }
  const css = (rgb, alpha) => alpha === undefined ? `rgb(${rgb[0]},${rgb[1]},${rgb[2]})`
                                                  : `rgba(${rgb[0]},${rgb[1]},${rgb[2]},${alpha})`;

  // Encounter kinds (tools/viewer/viewer_state.h); any other kind gets the fallback style.
  const kKinds = {
    direct: { label: 'direct encounter (one robot saw another)', color: [200, 0, 160], dash: [] },
    scan: { label: 'scan encounter (matched scans)', color: [230, 120, 0], dash: [6, 3] },
    loop: { label: 'loop closure', color: [0, 140, 70], dash: [2, 3] },
  };
  const kFallbackKind = { label: 'other kind', color: [90, 90, 90], dash: [8, 4, 2, 4] };

  // ---- view ---------------------------------------------------------------------------
  const canvas = document.getElementById('map');
  const view = { cx: 0, cy: 0, scale: 20, follow: true };
  let layout = { trajectories: [], offsets: new Map(), bounds: null };

  // Anchored trajectories and tiles in the global frame; each unanchored trajectory (in
  // its own local frame) placed apart, to the right of everything else.
  function computeLayout() {
    const list = sortedTrajectories();
    const box = { x0: Infinity, y0: Infinity, x1: -Infinity, y1: -Infinity };
    const grow = (b, x, y) => { b.x0 = Math.min(b.x0, x); b.y0 = Math.min(b.y0, y);
                                b.x1 = Math.max(b.x1, x); b.y1 = Math.max(b.y1, y); };
    for (const t of list) {
      if (!t.anchored) continue;
      for (let i = 0; i < t.poses.length; i += 3) grow(box, t.poses[i], t.poses[i + 1]);
    }
    for (const tile of model.tiles.values()) {
      grow(box, tile.x * tile.w * tile.res, tile.y * tile.h * tile.res);
      grow(box, (tile.x + 1) * tile.w * tile.res, (tile.y + 1) * tile.h * tile.res);
    }
    const offsets = new Map();
    let next = isFinite(box.x1) ? box.x1 + 3 : 0;
    const base = isFinite(box.y0) ? box.y0 : 0;
    for (const t of list) {
      if (t.anchored) { offsets.set(t.key, [0, 0]); continue; }
      const own = { x0: Infinity, y0: Infinity, x1: -Infinity, y1: -Infinity };
      for (let i = 0; i < t.poses.length; i += 3) grow(own, t.poses[i], t.poses[i + 1]);
      if (!isFinite(own.x0)) { offsets.set(t.key, [next, base]); continue; }
      const dx = next - own.x0, dy = base - own.y0;
      offsets.set(t.key, [dx, dy]);
      grow(box, own.x0 + dx, own.y0 + dy);
      grow(box, own.x1 + dx, own.y1 + dy);
      next = own.x1 + dx + 3;
    }
    layout = { trajectories: list, offsets: offsets, bounds: isFinite(box.x0) ? box : null };
  }

  function fitView() {
    const b = layout.bounds;
    if (!b) return;
    const w = canvas.width, h = canvas.height, margin = 40;  // room for the names
    view.cx = (b.x0 + b.x1) / 2;
    view.cy = (b.y0 + b.y1) / 2;
    view.scale = Math.min((w - 2 * margin) / Math.max(b.x1 - b.x0, 1),
                          (h - 2 * margin) / Math.max(b.y1 - b.y0, 1));
  }
  const toX = (x) => canvas.width / 2 + (x - view.cx) * view.scale;
  const toY = (y) => canvas.height / 2 - (y - view.cy) * view.scale;

  // ---- drawing ------------------------------------------------------------------------
  function draw() {
    const start = performance.now();
    const rect = canvas.getBoundingClientRect();
    if (canvas.width !== Math.round(rect.width) || canvas.height !== Math.round(rect.height)) {
      canvas.width = Math.round(rect.width);
      canvas.height = Math.round(rect.height);
    }
    computeLayout();
    if (view.follow) fitView();
    const g = canvas.getContext('2d');
    g.setTransform(1, 0, 0, 1, 0, 0);
    g.fillStyle = '#c8c8c8';
    g.fillRect(0, 0, canvas.width, canvas.height);

    g.imageSmoothingEnabled = false;
    for (const tile of model.tiles.values()) {
      const x0 = toX(tile.x * tile.w * tile.res), y1 = toY((tile.y + 1) * tile.h * tile.res);
      const size = tile.w * tile.res * view.scale, height = tile.h * tile.res * view.scale;
      if (x0 > canvas.width || y1 > canvas.height || x0 + size < 0 || y1 + height < 0) continue;
      g.drawImage(tile.image, x0, y1, size, height);
    }

    const byKey = new Map(layout.trajectories.map((t) => [t.key, t]));
    // Anchor covariances: 2-sigma ellipses of the anchor's (x, y) at the anchor position.
    if (model.covariances) {
      for (const a of model.covariances.anchors) {
        const t = byKey.get(a.key);
        if (!t || !t.anchored) continue;
        const c = a.cov, sxx = c[0], sxy = c[1], syy = c[4];
        const mean = (sxx + syy) / 2, d = Math.sqrt(Math.max(0, ((sxx - syy) / 2) ** 2 + sxy * sxy));
        const l1 = mean + d, l2 = Math.max(0, mean - d);
        const angle = 0.5 * Math.atan2(2 * sxy, sxx - syy);
        const rx = Math.max(2, 2 * Math.sqrt(l1) * view.scale), ry = Math.max(2, 2 * Math.sqrt(l2) * view.scale);
        g.beginPath();
        g.ellipse(toX(a.anchor[0]), toY(a.anchor[1]), rx, ry, -angle, 0, 2 * Math.PI);
        g.fillStyle = css(t.color, 0.15);
        g.fill();
        g.strokeStyle = css(t.color, 0.9);
        g.lineWidth = 1;
        g.setLineDash([]);
        g.stroke();
      }
    }

    g.lineJoin = 'round';
    g.lineCap = 'round';
    for (const t of layout.trajectories) {
      const [dx, dy] = layout.offsets.get(t.key);
      g.strokeStyle = css(t.color);
      g.lineWidth = 3;
      g.setLineDash(t.anchored ? [] : [8, 5]);
      g.beginPath();
      for (let i = 0; i < t.poses.length; i += 3) {
        const x = toX(t.poses[i] + dx), y = toY(t.poses[i + 1] + dy);
        if (i === 0) g.moveTo(x, y); else g.lineTo(x, y);
      }
      if (t.poses.length === 3) g.lineTo(toX(t.poses[0] + dx) + 0.1, toY(t.poses[1] + dy));
      g.stroke();
    }
    g.setLineDash([]);

    g.lineWidth = 1.5;
    for (const l of model.links) {
      const a = byKey.get(l[0]), b = byKey.get(l[2]);
      if (!a || !b || 3 * l[1] + 1 >= a.poses.length || 3 * l[3] + 1 >= b.poses.length) continue;
      const oa = layout.offsets.get(a.key), ob = layout.offsets.get(b.key);
      const style = kKinds[l[4]] || kFallbackKind;
      g.strokeStyle = css(style.color);
      g.setLineDash(style.dash);
      g.beginPath();
      g.moveTo(toX(a.poses[3 * l[1]] + oa[0]), toY(a.poses[3 * l[1] + 1] + oa[1]));
      g.lineTo(toX(b.poses[3 * l[3]] + ob[0]), toY(b.poses[3 * l[3] + 1] + ob[1]));
      g.stroke();
    }
    g.setLineDash([]);

    // Each robot's newest pose: a heading mark and its name.
    g.font = 'bold 12px sans-serif';
    for (const t of layout.trajectories) {
      const n = t.poses.length;
      if (n < 3) continue;
      const [dx, dy] = layout.offsets.get(t.key);
      const x = toX(t.poses[n - 3] + dx), y = toY(t.poses[n - 2] + dy), th = t.poses[n - 1];
      g.fillStyle = css(t.color);
      g.beginPath();
      g.moveTo(x + 9 * Math.cos(th), y - 9 * Math.sin(th));
      g.lineTo(x + 5 * Math.cos(th + 2.4), y - 5 * Math.sin(th + 2.4));
      g.lineTo(x + 5 * Math.cos(th - 2.4), y - 5 * Math.sin(th - 2.4));
      g.closePath();
      g.fill();
      const label = t.anchored ? t.robot : t.robot + ' (unanchored)';
      g.lineWidth = 3;
      g.strokeStyle = 'rgba(255,255,255,0.85)';
      g.strokeText(label, x + 8, y - 8);
      g.fillText(label, x + 8, y - 8);
    }

    const ms = performance.now() - start;
    stats.frames++;
    stats.lastFrameMs = ms;
    stats.maxFrameMs = Math.max(stats.maxFrameMs, ms);
    stats.totalFrameMs += ms;
    updatePanels();
  }

  let drawPending = false;
  function requestDraw() {
    if (drawPending) return;
    drawPending = true;
    requestAnimationFrame(() => { drawPending = false; draw(); });
  }

  // ---- panels -------------------------------------------------------------------------
  function cell(text, cls) {
    const td = document.createElement('td');
    td.textContent = text;
    if (cls) td.className = cls;
    return td;
  }
  function row(table, cells) {
    const tr = document.createElement('tr');
    for (const c of cells) tr.appendChild(c);
    table.appendChild(tr);
  }
  function swatch(rgb, dash) {
    const td = document.createElement('td');
    const s = document.createElement('span');
    s.className = 'swatch';
    s.style.background = dash && dash.length
      ? `repeating-linear-gradient(90deg, ${css(rgb)} 0 5px, transparent 5px 8px)` : css(rgb);
    td.appendChild(s);
    return td;
  }
  const time = (utime) => utime > 0 ? new Date(utime / 1000).toISOString().replace('T', ' ').slice(0, 23) : '-';

  function updatePanels() {
    const legend = document.getElementById('legend');
    legend.textContent = '';
    row(legend, [cell(''), cell('robot'), cell('trajectory'), cell('keyframes', 'n')]);
    for (const t of layout.trajectories) {
      row(legend, [swatch(t.color, t.anchored ? [] : [1]),
                   cell(t.anchored ? t.robot : t.robot + ' (unanchored)', t.anchored ? '' : 'unanchored'),
                   cell(String(t.id)), cell(String(t.poses.length / 3), 'n')]);
    }
    const kinds = document.getElementById('legend-kinds');
    kinds.textContent = '';
    const seen = new Set(model.links.map((l) => l[4]));
    for (const [name, style] of Object.entries(kKinds)) {
      row(kinds, [swatch(style.color, style.dash), cell(style.label), cell(String(model.links.filter((l) => l[4] === name).length), 'n')]);
    }
    for (const name of seen) {
      if (!(name in kKinds)) row(kinds, [swatch(kFallbackKind.color, kFallbackKind.dash), cell(name + ' (' + kFallbackKind.label + ')'), cell(String(model.links.filter((l) => l[4] === name).length), 'n')]);
    }
    row(kinds, [swatch([30, 30, 30]), cell('occupied / free (white) / unknown (grey)'), cell('')]);
    row(kinds, [swatch([120, 120, 120]), cell('anchor covariance, 2 sigma'), cell('')]);

    const status = document.getElementById('status');
    status.textContent = '';
    const s = model.status;
    const add = (name, value) => row(status, [cell(name), cell(String(value), 'n')]);
    if (s) {
      add('robots', s.robots);
      add('trajectories', s.trajectories + ' (' + s.anchored + ' anchored)');
      add('keyframes', s.keyframes);
      add('encounters', s.encounters);
      add('solver update', s.update + ' (' + s.last_update_ms.toFixed(1) + ' ms)');
      add('status data time', time(s.utime));
    } else {
      add('status', 'none yet');
    }
    add('map update', model.mapUpdate);
    add('map data time', time(model.mapUtime));
    add('last message (viewer)', time(model.wallUtime));
    add('server restarts seen', model.restarts);
    const rejections = document.getElementById('rejections');
    rejections.textContent = '';
    const reasons = s ? Object.entries(s.rejections) : [];
    if (reasons.length === 0) row(rejections, [cell(s ? 'none' : '-')]);
    for (const [reason, count] of reasons) row(rejections, [cell(reason), cell(String(count), 'n')]);

    const viewer = document.getElementById('viewer');
    viewer.textContent = '';
    const addv = (name, value) => row(viewer, [cell(name), cell(String(value), 'n')]);
    addv('messages', stats.messages + ' (' + stats.fulls + ' full)');
    addv('received', (stats.bytes / 1e6).toFixed(2) + ' MB');
    addv('tiles', model.tiles.size);
    addv('frame', stats.lastFrameMs.toFixed(1) + ' ms');
    document.getElementById('viewer-state').textContent = JSON.stringify(pageState());
  }

  // ---- the page's own state (for tests and the benchmark) ------------------------------
  function pageState() {
    const rect = canvas.getBoundingClientRect();
    return {
      seq: model.seq, restarts: model.restarts, map_update: model.mapUpdate,
      connected: stats.connected, fulls: stats.fulls, deltas: stats.deltas, messages: stats.messages,
      bytes: stats.bytes, frames: stats.frames, last_frame_ms: stats.lastFrameMs,
      max_frame_ms: stats.maxFrameMs, mean_frame_ms: stats.frames ? stats.totalFrameMs / stats.frames : 0,
      tiles: model.tiles.size, encounters: model.links.length,
      view: { cx: view.cx, cy: view.cy, scale: view.scale, left: rect.left, top: rect.top,
              width: canvas.width, height: canvas.height, device_pixel_ratio: window.devicePixelRatio,
              follow: view.follow, bounds: layout.bounds },
      trajectories: layout.trajectories.map((t) => ({
        key: t.key, robot: t.robot, id: t.id, anchored: t.anchored, keyframes: t.poses.length / 3,
        color: t.color, offset: layout.offsets.get(t.key) })),
    };
  }

  // ---- save: the canvas as PNG, the merged graph as g2o ---------------------------------
  function download(blob, name) {
    const url = URL.createObjectURL(blob);
    const a = document.createElement('a');
    a.href = url;
    a.download = name;
    document.body.appendChild(a);
    a.click();
    a.remove();
    setTimeout(() => URL.revokeObjectURL(url), 1000);
  }
  const wrap = (a) => Math.atan2(Math.sin(a), Math.cos(a));
  function between(p, q) {  // q in p's frame
    const dx = q[0] - p[0], dy = q[1] - p[1], c = Math.cos(p[2]), s = Math.sin(p[2]);
    return [c * dx + s * dy, -s * dx + c * dy, wrap(q[2] - p[2])];
  }
  // Like anchormap-render --g2o: a vertex per keyframe, an edge between consecutive
  // keyframes and one per encounter, measured from the current estimates, identity
  // information (the server's output carries no measurement covariances).
  function g2oText() {
    const lines = [], first = new Map();
    let next = 0;
    const pose = (t, i) => [t.poses[3 * i], t.poses[3 * i + 1], t.poses[3 * i + 2]];
    const edge = (a, b, z) => lines.push(`EDGE_SE2 ${a} ${b} ${z[0]} ${z[1]} ${z[2]} 1 0 0 1 0 1`);
    for (const t of layout.trajectories) {
      first.set(t.key, next);
      const n = t.poses.length / 3;
      for (let i = 0; i < n; i++) {
        const p = pose(t, i);
        lines.push(`VERTEX_SE2 ${next + i} ${p[0]} ${p[1]} ${p[2]}`);
        if (i > 0) edge(next + i - 1, next + i, between(pose(t, i - 1), p));
      }
      next += n;
    }
    const byKey = new Map(layout.trajectories.map((t) => [t.key, t]));
    for (const l of model.links) {
      const a = byKey.get(l[0]), b = byKey.get(l[2]);
      if (!a || !b || l[1] >= a.poses.length / 3 || l[3] >= b.poses.length / 3) continue;
      edge(first.get(l[0]) + l[1], first.get(l[2]) + l[3], between(pose(a, l[1]), pose(b, l[3])));
    }
    return lines.join('\n') + '\n';
  }
  const stamp = () => 'anchormap-update-' + model.mapUpdate;
  function pngBlob() {
    draw();
    return new Promise((resolve) => canvas.toBlob(resolve, 'image/png'));
  }
  document.getElementById('save-png').onclick = () =>
    pngBlob().then((blob) => download(blob, stamp() + '.png'));
  document.getElementById('save-g2o').onclick = () =>
    download(new Blob([g2oText()], { type: 'text/plain' }), stamp() + '.g2o');
  document.getElementById('fit').onclick = () => { view.follow = true; requestDraw(); };

  // ---- pan and zoom -------------------------------------------------------------------
  let drag = null;
  canvas.addEventListener('mousedown', (e) => { drag = { x: e.clientX, y: e.clientY }; canvas.style.cursor = 'grabbing'; });
  window.addEventListener('mouseup', () => { drag = null; canvas.style.cursor = 'grab'; });
  window.addEventListener('mousemove', (e) => {
    if (!drag) return;
    view.follow = false;
    view.cx -= (e.clientX - drag.x) / view.scale;
    view.cy += (e.clientY - drag.y) / view.scale;
    drag = { x: e.clientX, y: e.clientY };
    requestDraw();
  });
  canvas.addEventListener('wheel', (e) => {
    e.preventDefault();
    view.follow = false;
    const rect = canvas.getBoundingClientRect();
    const mx = e.clientX - rect.left, my = e.clientY - rect.top;
    const wx = view.cx + (mx - canvas.width / 2) / view.scale;
    const wy = view.cy - (my - canvas.height / 2) / view.scale;
    view.scale *= Math.exp(-e.deltaY * 0.0015);
    view.scale = Math.min(2000, Math.max(0.01, view.scale));
    view.cx = wx - (mx - canvas.width / 2) / view.scale;
    view.cy = wy + (my - canvas.height / 2) / view.scale;
    requestDraw();
  }, { passive: false });
  window.addEventListener('resize', requestDraw);

  // ---- connection ---------------------------------------------------------------------
  function connect() {
    const socket = new WebSocket('ws://' + location.host + '/ws');
    const badge = document.getElementById('connection');
    socket.onopen = () => {
      stats.connected = true;
      badge.textContent = 'live';
      badge.className = 'ok';
      socket.send(JSON.stringify({ type: 'hello' }));
    };
    socket.onmessage = (event) => {
      stats.messages++;
      stats.bytes += event.data.length;
      let message;
      try { message = JSON.parse(event.data); } catch (e) { return; }
      applyMessage(message);
      requestDraw();
    };
    socket.onclose = () => {
      stats.connected = false;
      badge.textContent = 'disconnected: retrying';
      badge.className = 'bad';
      setTimeout(connect, 1000);
    };
  }

  window.anchormapViewer = { state: pageState, draw: draw, g2o: g2oText, pngBlob: pngBlob };
  connect();
  requestDraw();
})();
