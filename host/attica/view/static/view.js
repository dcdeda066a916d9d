// attica view: the page of `attica view` (attica, MIT licence). Plain JavaScript, Canvas 2D; no library.
//
// The server sends {"type": "hello"} once, then {"type": "update", "state": ..., "history": [...]} at
// display rate; after drawing an update the page answers {"type": "ack"}, and only then gets the next
// (latest wins: a slow or hidden tab gets fewer updates, never a backlog).
//
// The scene: a fixed display frame with x east, y north, z up (ENU); the node's quaternion q (sensor-to-
// earth in the node's convention) is brought to it by q_enu = conj(c) * q with c the rotation
// convention <- ENU of att_calib.h; the earth axes are labelled in the convention. A perspective camera
// orbits the origin (azimuth, elevation, distance, vertical field of view); window.atticaView exposes
// the camera and the scene so that a test can check where the body's nose is drawn.
(function () {
  "use strict";

  const $ = (id) => document.getElementById(id);
  const DEG = 180 / Math.PI;
  const A = Math.SQRT1_2;
  // c: the rotation convention <- ENU (att_calib.h: q_conv = c * q_enu)
  const CONV = { ENU: [1, 0, 0, 0], NED: [0, A, A, 0], NWU: [A, 0, 0, -A] };
  // the earth axes of each convention in the display frame (ENU), with their names
  const EARTH = {
    ENU: [[[1, 0, 0], "x E"], [[0, 1, 0], "y N"], [[0, 0, 1], "z U"]],
    NED: [[[0, 1, 0], "x N"], [[1, 0, 0], "y E"], [[0, 0, -1], "z D"]],
    NWU: [[[0, 1, 0], "x N"], [[-1, 0, 0], "y W"], [[0, 0, 1], "z U"]],
  };
  const NOSE = [1.75, 0, 0]; // the body's nose marker, body frame
  const NOSE_RGB = [235, 40, 40];
  const BOX = [1.0, 0.62, 0.16]; // half extents of the board, body frame
  const GRID_Z = -1.3;
  const CAM0 = { az: -55 / DEG, el: 28 / DEG, dist: 7.2, fov: 38 / DEG };

  const S = {
    hello: null, state: null, ws: null, connected: false, history: [], epoch: null,
    cam: Object.assign({}, CAM0), drawn: 0, updates: 0, scheduled: false, retry: 500,
    qConv: null, qDisp: null, truth: null, lastCam: null, pendingCommand: null, eventsSeen: 0,
  };

  // --- quaternions (w, x, y, z) ---------------------------------------------------------------------
  function qmul(a, b) {
    return [
      a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
      a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
      a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
      a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ];
  }
  const qconj = (q) => [q[0], -q[1], -q[2], -q[3]];
  function qnorm(q) {
    const n = Math.hypot(q[0], q[1], q[2], q[3]);
    return n > 0 ? q.map((v) => v / n) : [1, 0, 0, 0];
  }
  function qmat(q) { // rows of R: v_earth = R v_body
    const [w, x, y, z] = q;
    return [
      [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
      [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
      [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ];
  }
  const mv = (R, v) => [0, 1, 2].map((i) => R[i][0] * v[0] + R[i][1] * v[1] + R[i][2] * v[2]);
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
  const scale = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const unit = (a) => scale(a, 1 / Math.hypot(a[0], a[1], a[2]));
  const finite = (v) => typeof v === "number" && Number.isFinite(v);

  // --- camera -----------------------------------------------------------------------------------------
  function camera(width, height) {
    const c = S.cam;
    const pos = [c.dist * Math.cos(c.el) * Math.cos(c.az), c.dist * Math.cos(c.el) * Math.sin(c.az),
      c.dist * Math.sin(c.el)];
    const fwd = unit(scale(pos, -1));
    const right = unit(cross(fwd, [0, 0, 1]));
    const up = cross(right, fwd);
    const f = 0.5 * height / Math.tan(c.fov / 2);
    return { pos, fwd, right, up, f, cx: width / 2, cy: height / 2, width, height,
      az: c.az, el: c.el, dist: c.dist, fov: c.fov };
  }
  function project(cam, p) {
    const v = sub(p, cam.pos);
    const zc = dot(v, cam.fwd);
    return [cam.cx + cam.f * dot(v, cam.right) / zc, cam.cy - cam.f * dot(v, cam.up) / zc, zc];
  }

  // --- drawing helpers ------------------------------------------------------------------------------
  function fitCanvas(cv) {
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(cv.clientWidth * dpr));
    const h = Math.max(1, Math.round(cv.clientHeight * dpr));
    if (cv.width !== w || cv.height !== h) { cv.width = w; cv.height = h; }
    const ctx = cv.getContext("2d");
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    return [ctx, cv.clientWidth, cv.clientHeight];
  }
  function line(ctx, cam, a, b, style, width, dash) {
    const pa = project(cam, a);
    const pb = project(cam, b);
    if (pa[2] <= 0.05 || pb[2] <= 0.05) return;
    ctx.strokeStyle = style;
    ctx.lineWidth = width || 1;
    ctx.setLineDash(dash || []);
    ctx.beginPath();
    ctx.moveTo(pa[0], pa[1]);
    ctx.lineTo(pb[0], pb[1]);
    ctx.stroke();
    ctx.setLineDash([]);
  }
  function label(ctx, cam, p, text, color) {
    const pp = project(cam, p);
    if (pp[2] <= 0.05) return;
    ctx.fillStyle = color;
    ctx.font = "600 13px system-ui, sans-serif";
    ctx.textAlign = "center";
    ctx.textBaseline = "middle";
    ctx.fillText(text, pp[0], pp[1]);
  }
  function boxCorners(R, half, center) {
    const out = [];
    for (const sx of [-1, 1]) for (const sy of [-1, 1]) for (const sz of [-1, 1]) {
      out.push(add(center, mv(R, [sx * half[0], sy * half[1], sz * half[2]])));
    }
    return out; // index = (sx>0)*4 + (sy>0)*2 + (sz>0)
  }
  const FACES = [ // corner indices, body-frame normal, base colour
    [[4, 6, 7, 5], [1, 0, 0], [170, 80, 80]], [[0, 1, 3, 2], [-1, 0, 0], [110, 110, 120]],
    [[2, 3, 7, 6], [0, 1, 0], [100, 150, 105]], [[0, 4, 5, 1], [0, -1, 0], [110, 110, 120]],
    [[1, 5, 7, 3], [0, 0, 1], [95, 125, 170]], [[0, 2, 6, 4], [0, 0, -1], [70, 78, 90]],
  ];

  function drawScene() {
    const cv = $("scene");
    const [ctx, w, h] = fitCanvas(cv);
    const cam = camera(w, h);
    S.lastCam = cam;
    ctx.fillStyle = "#0d1319";
    ctx.fillRect(0, 0, w, h);
    const st = S.state;
    const conv = (st && st.convention) || "ENU";
    // the earth grid and axes
    for (let i = -4; i <= 4; i++) {
      const style = i === 0 ? "#3a4a5a" : "#222d38";
      line(ctx, cam, [i, -4, GRID_Z], [i, 4, GRID_Z], style, 1);
      line(ctx, cam, [-4, i, GRID_Z], [4, i, GRID_Z], style, 1);
    }
    const origin = [0, 0, GRID_Z];
    for (const [dir, name] of EARTH[conv]) {
      const tip = add(origin, scale(dir, 2.6));
      line(ctx, cam, origin, tip, "#8796a5", 1.5, [5, 4]);
      label(ctx, cam, add(origin, scale(dir, 2.9)), name, "#aeb9c4");
    }
    label(ctx, cam, [0, 4.4, GRID_Z], "N", "#5d6b79");
    label(ctx, cam, [4.4, 0, GRID_Z], "E", "#5d6b79");
    label(ctx, cam, [0, -4.4, GRID_Z], "S", "#5d6b79");
    label(ctx, cam, [-4.4, 0, GRID_Z], "W", "#5d6b79");
    // the body
    const att = st && st.att;
    S.qConv = att && att.q && att.q.every(finite) ? att.q : null;
    S.qDisp = S.qConv ? qnorm(qmul(qconj(CONV[conv] || CONV.ENU), S.qConv)) : null;
    if (!S.qDisp) {
      ctx.fillStyle = "#7d8b99";
      ctx.font = "15px system-ui, sans-serif";
      ctx.textAlign = "center";
      ctx.fillText("waiting for the node's attitude…", w / 2, h / 2);
      drawGhost(ctx, cam, st);
      return;
    }
    const R = qmat(S.qDisp);
    const corners = boxCorners(R, BOX, [0, 0, 0]);
    const light = unit([0.3, -0.5, 1]);
    const items = [];
    for (const [idx, nb, rgb] of FACES) {
      const n = mv(R, nb);
      const center = scale(idx.reduce((acc, i) => add(acc, corners[i]), [0, 0, 0]), 0.25);
      if (dot(n, sub(cam.pos, center)) <= 0) continue; // back face
      const k = 0.55 + 0.45 * Math.max(0, dot(n, light));
      const depth = dot(sub(center, cam.pos), cam.fwd);
      items.push({ depth, draw: () => {
        ctx.beginPath();
        idx.forEach((i, j) => {
          const p = project(cam, corners[i]);
          if (j === 0) ctx.moveTo(p[0], p[1]); else ctx.lineTo(p[0], p[1]);
        });
        ctx.closePath();
        ctx.fillStyle = `rgb(${rgb.map((v) => Math.round(v * k)).join(",")})`;
        ctx.fill();
        ctx.strokeStyle = "rgba(10,14,18,0.8)";
        ctx.lineWidth = 1;
        ctx.stroke();
      } });
    }
    const axes = [[[1, 0, 0], BOX[0], NOSE[0], "#eb2828"], [[0, 1, 0], BOX[1], 1.15, "#3cc850"],
      [[0, 0, 1], BOX[2], 0.9, "#3c8cff"]];
    for (const [dir, from, to, color] of axes) {
      const steps = 6;
      for (let s = 0; s < steps; s++) {
        const a = mv(R, scale(dir, from + (to - from) * s / steps));
        const b = mv(R, scale(dir, from + (to - from) * (s + 1) / steps));
        const depth = dot(sub(scale(add(a, b), 0.5), cam.pos), cam.fwd);
        items.push({ depth, draw: () => line(ctx, cam, a, b, color, 3.5) });
      }
    }
    items.sort((p, q) => q.depth - p.depth);
    for (const it of items) it.draw();
    // the nose marker and the axis names, on top
    const nose = mv(R, NOSE);
    const pn = project(cam, nose);
    ctx.fillStyle = `rgb(${NOSE_RGB.join(",")})`;
    ctx.beginPath();
    ctx.arc(pn[0], pn[1], 7, 0, 2 * Math.PI);
    ctx.fill();
    label(ctx, cam, mv(R, [NOSE[0] + 0.3, 0, 0]), "x", "#ff8a8a");
    label(ctx, cam, mv(R, [0, 1.35, 0]), "y", "#8ce99a");
    label(ctx, cam, mv(R, [0, 0, 1.1]), "z", "#91c4ff");
    drawGhost(ctx, cam, st);
  }

  // the truth ghost (simulator or recording): a dashed wire box and its x axis, over the body
  function drawGhost(ctx, cam, st) {
    S.truth = st && st.truth && st.truth.q && st.truth.q.every(finite) ? qnorm(st.truth.q) : null;
    if (S.truth) {
      const R = qmat(S.truth);
      const c = boxCorners(R, BOX, [0, 0, 0]);
      const edges = [[0, 1], [2, 3], [4, 5], [6, 7], [0, 2], [1, 3], [4, 6], [5, 7], [0, 4], [1, 5], [2, 6], [3, 7]];
      for (const [a, b] of edges) line(ctx, cam, c[a], c[b], "rgba(230,236,245,0.55)", 1.2, [4, 3]);
      line(ctx, cam, mv(R, [BOX[0], 0, 0]), mv(R, NOSE), "rgba(230,236,245,0.7)", 2, [4, 3]);
    }
  }

  // --- plots ------------------------------------------------------------------------------------------
  const COLORS = ["#ff6b6b", "#51cf66", "#4dabf7"];
  function drawPlot(id, series, opts) {
    const [ctx, w, h] = fitCanvas($(id));
    ctx.clearRect(0, 0, w, h);
    const L = 44, Rm = 6, T = 6, B = 16;
    const pw = w - L - Rm, ph = h - T - B;
    const span = 30;
    const tmax = S.history.length ? S.history[S.history.length - 1][1] : 0;
    const tmin = tmax - span;
    let lo = Infinity, hi = -Infinity;
    for (const s of series) for (const p of s) if (finite(p[1]) && p[0] >= tmin) { lo = Math.min(lo, p[1]); hi = Math.max(hi, p[1]); }
    if (opts.ref !== undefined && finite(opts.ref)) { lo = Math.min(lo, opts.ref); hi = Math.max(hi, opts.ref); }
    if (opts.fixed) { lo = opts.fixed[0]; hi = opts.fixed[1]; }
    if (!finite(lo) || !finite(hi)) { lo = -1; hi = 1; }
    if (hi - lo < (opts.minSpan || 1e-3)) { const m = (hi + lo) / 2; lo = m - (opts.minSpan || 1e-3) / 2; hi = m + (opts.minSpan || 1e-3) / 2; }
    const pad = opts.fixed ? 0 : 0.08 * (hi - lo);
    lo -= pad; hi += pad;
    const X = (t) => L + pw * (t - tmin) / span;
    const Y = (v) => T + ph * (1 - (v - lo) / (hi - lo));
    ctx.font = "11px ui-monospace, monospace";
    ctx.fillStyle = "#7d8b99";
    ctx.textAlign = "right";
    ctx.textBaseline = "middle";
    ctx.strokeStyle = "#222d38";
    ctx.lineWidth = 1;
    const ticks = opts.ticks || [lo + (hi - lo) * 0.1, (lo + hi) / 2, hi - (hi - lo) * 0.1];
    for (const v of ticks) {
      ctx.beginPath(); ctx.moveTo(L, Y(v)); ctx.lineTo(L + pw, Y(v)); ctx.stroke();
      ctx.fillText(Math.abs(v) >= 100 ? v.toFixed(0) : v.toFixed(opts.digits === undefined ? 2 : opts.digits), L - 4, Y(v));
    }
    ctx.textAlign = "center";
    for (let k = 0; k <= 30; k += 10) ctx.fillText(k === 30 ? "now" : `-${30 - k} s`, X(tmin + k), h - 7);
    if (opts.ref !== undefined && finite(opts.ref)) {
      ctx.strokeStyle = "#aeb9c4"; ctx.setLineDash([5, 4]);
      ctx.beginPath(); ctx.moveTo(L, Y(opts.ref)); ctx.lineTo(L + pw, Y(opts.ref)); ctx.stroke();
      ctx.setLineDash([]);
    }
    ctx.save();
    ctx.beginPath(); ctx.rect(L, T, pw, ph); ctx.clip();
    series.forEach((s, i) => {
      ctx.strokeStyle = (opts.colors || COLORS)[i % 3];
      ctx.lineWidth = 1.5;
      ctx.beginPath();
      let pen = false, prev = null;
      for (const p of s) {
        if (p[0] < tmin - 1 || !finite(p[1])) { pen = false; continue; }
        // an angle wrapping from +180 to -180 is not a line across the plot
        if (opts.wrap && prev !== null && Math.abs(p[1] - prev) > 180) pen = false;
        if (pen) ctx.lineTo(X(p[0]), Y(p[1])); else ctx.moveTo(X(p[0]), Y(p[1]));
        pen = true; prev = p[1];
      }
      ctx.stroke();
    });
    ctx.restore();
    if (!S.history.length) {
      ctx.fillStyle = "#5d6b79"; ctx.textAlign = "center"; ctx.fillText("no data yet", L + pw / 2, T + ph / 2);
    }
  }
  function drawPlots() {
    const hist = S.history;
    const col = (j, k) => hist.map((p) => [p[1], finite(p[j]) ? p[j] * k : NaN]);
    const st = S.state;
    const imu = (st && st.imu) || {};
    drawPlot("plot-euler", [col(2, DEG), col(3, DEG), col(4, DEG)],
      { fixed: [-180, 180], ticks: [-180, -90, 0, 90, 180], digits: 0, wrap: true });
    drawPlot("plot-bias", [col(5, DEG), col(6, DEG), col(7, DEG)], { minSpan: 0.05, digits: 3 });
    drawPlot("plot-acc", [col(8, 1)], { ref: imu.g_ref, minSpan: 0.5, colors: ["#ffd43b"] });
    drawPlot("plot-mag", [col(9, 1)], { ref: imu.m_ref === null ? undefined : imu.m_ref, minSpan: 2, colors: ["#da77f2"] });
  }

  // --- panels -----------------------------------------------------------------------------------------
  const fmt = (v, d) => (finite(v) ? v.toFixed(d) : "–");
  const clock = (t) => new Date(t * 1000).toLocaleTimeString([], { hour12: false });
  function setText(id, text) { const el = $(id); if (el && el.textContent !== text) el.textContent = text; }

  function buildStatic() {
    const h = S.hello;
    setText("version", `attica ${h.version}`);
    const flags = $("flags");
    flags.textContent = "";
    for (const f of h.flags) {
      const el = document.createElement("span");
      el.className = `flag ${f.severity}`;
      el.id = `flag-${f.name}`;
      el.dataset.bit = String(f.bit);
      el.title = `${f.name}: ${f.text}`;
      el.textContent = f.label;
      flags.appendChild(el);
    }
    const lights = $("lights");
    lights.textContent = "";
    for (const [key, text, sev] of LIGHTS) {
      const el = document.createElement("span");
      el.className = `light ${sev}`;
      el.id = `light-${key}`;
      el.textContent = text;
      lights.appendChild(el);
    }
    const kind = $("cmd-kind");
    kind.textContent = "";
    for (const k of h.kinds) { const o = document.createElement("option"); o.value = k; o.textContent = k; kind.appendChild(o); }
    const conv = $("cmd-conv");
    conv.textContent = "";
    for (const c of h.conventions) { const o = document.createElement("option"); o.value = c; o.textContent = c; conv.appendChild(o); }
    const speed = $("pb-speed");
    speed.textContent = "";
    for (const s of h.speeds) { const o = document.createElement("option"); o.value = String(s); o.textContent = `${s}×`; speed.appendChild(o); }
  }

  const LIGHTS = [
    ["crc_errors", "CRC", "bad"], ["counter_gaps", "gap", "warn"], ["repeats", "repeat", "warn"],
    ["dlc_errors", "DLC", "bad"], ["unknown_ids", "unknown ID", "warn"], ["missing_sets", "lost sets", "warn"],
    ["dropped", "dropped", "bad"], ["silent", "silent", "bad"], ["view_errors", "view error", "bad"],
  ];
  const HEALTH_ROWS = [
    ["frames_per_s", "frames/s", (h) => fmt(h.frames_per_s, 0)],
    ["bus_load", "bus load", (h) => (finite(h.bus_load) ? `${(100 * h.bus_load).toFixed(1)} % of ${h.bitrate / 1000} kbit/s` : "–")],
    ["frames", "frames seen", (h) => String(h.frames)],
    ["crc_errors", "E2E CRC errors", (h) => `${h.crc_errors}` + (h.crc_unchecked ? ` (unchecked ${h.crc_unchecked})` : "")],
    ["counter_gaps", "counter gaps", (h) => `${h.counter_gaps} (${h.missing_frames} frames)`],
    ["repeats", "counter repeats", (h) => String(h.repeats)],
    ["dlc_errors", "DLC errors", (h) => String(h.dlc_errors)],
    ["unknown_ids", "unknown IDs", (h) => String(h.unknown_ids)],
    ["other", "other frames", (h) => String(h.other)],
    ["missing_sets", "output sets lost", (h) => String(h.missing_sets)],
    ["dropped", "dropped by the reader", (h) => String(h.dropped)],
    ["latency_ms", "latency IMU → set", (h) => (finite(h.latency_ms) ? `${h.latency_ms.toFixed(2)} ms (max ${h.latency_max_ms.toFixed(2)})` : "–")],
    ["silent_s", "last frame", (h) => (finite(h.silent_s) ? `${h.silent_s.toFixed(1)} s ago` : "none yet")],
  ];
  const DIAG_ROWS = ["crc_errors", "counter_gaps", "dlc_errors", "unknown_ids", "duplicates", "stale_partials"];
  const BUS_ROWS = ["bus_off", "recoveries", "error_passive", "error_warning", "rx_overruns"];

  function table(id, rows) {
    const t = $(id);
    if (t.rows.length !== rows.length) {
      t.textContent = "";
      for (const [key, name] of rows) {
        const tr = t.insertRow();
        tr.id = `${id}-row-${key}`;
        tr.insertCell().textContent = name;
        const td = tr.insertCell();
        td.id = `${id === "health" ? "h" : "d"}-${key}`;
      }
    }
    rows.forEach(([key, , value, hot], i) => {
      const td = t.rows[i].cells[1];
      if (td.textContent !== value) td.textContent = value;
      t.rows[i].classList.toggle("hot", !!hot);
    });
  }

  function drawPanels() {
    const st = S.state;
    if (!st) return;
    const src = st.source || {};
    setText("source", src.text || src.kind || "");
    const ss = $("source-state");
    const sstate = src.state || "starting";
    setText("source-state", sstate);
    ss.className = `pill ${sstate}`;
    const banner = $("banner");
    banner.hidden = !src.error;
    setText("banner", src.error || "");
    // readout
    const att = st.att;
    const e = att ? att.euler : null;
    setText("roll", e ? fmt(e[0] * DEG, 1) : "–");
    setText("pitch", e ? fmt(e[1] * DEG, 1) : "–");
    setText("yaw", e ? fmt(e[2] * DEG, 1) : "–");
    document.querySelector(".readout").classList.toggle("stale", !att || (finite(att.age) && att.age > 1.0));
    setText("att-meta", att ? `${att.kind} · steps ${att.steps} · ${st.convention}${att.fd ? " · CAN FD" : ""}` +
      (finite(att.age) && att.age > 1.0 ? ` · ${att.age.toFixed(1)} s old` : "") : "no output set yet");
    setText("legend-earth", `earth ${st.convention}`);
    $("legend-truth").hidden = !st.truth;
    // flags
    const word = att ? att.flags : 0;
    setText("flags-word", att ? `0x${word.toString(16).padStart(4, "0")}` : "");
    for (const el of $("flags").children) el.classList.toggle("on", !!att && (word & Number(el.dataset.bit)) !== 0);
    // health
    const h = st.health;
    const recent = new Set(h.recent || []);
    const silent = finite(h.silent_s) && h.silent_s > 2.0 && src.state !== "paused" && src.state !== "ended";
    for (const [key] of LIGHTS) {
      const on = key === "silent" ? silent : recent.has(key);
      $(`light-${key}`).classList.toggle("on", on);
    }
    table("health", HEALTH_ROWS.map(([key, name, f]) => [key, name, f(h), recent.has(key)]));
    const d = st.diag;
    const drows = DIAG_ROWS.map((k) => [k, k.replace("_", " "), d ? String(d[k]) : "–", d && d[k] > 0]);
    drows.push(["error_count", "error count (ATT_STATUS)", att ? String(att.error_count) : "–", att && att.error_count > 0]);
    const b = st.diag_bus; // only from a node whose port reports its CAN controller (ATT_DIAG_BUS)
    if (b) {
      drows.push(["bus_state", "CAN controller", b.state, b.state !== "ACTIVE"]);
      for (const k of BUS_ROWS) drows.push([`bus_${k}`, k.replace("_", " "), String(b[k]), b[k] > 0]);
      drows.push(["bus_lec", "last bus error", b.lec, b.lec !== "NONE"]);
    }
    table("diag", drows);
    // commands
    const canCmd = S.hello && S.hello.can_command && st.can_command;
    for (const id of ["cmd-reset", "cmd-select", "cmd-convention", "cmd-kind", "cmd-conv"]) $(id).disabled = !canCmd;
    const off = $("commands-off");
    off.hidden = !!canCmd;
    if (!canCmd) setText("commands-off", S.hello && S.hello.read_only ? "read-only: commands are off (--read-only)"
      : "commands need a live bus with a node (this source is a " + (src.kind || "?") + ")");
    list("cmd-log", (st.commands || []).slice().reverse(), (c) => [
      c.status === "sent" ? "" : c.status === "ok" ? "ok" : "fail",
      `${clock(c.t)} ${c.text}: ${c.status}${c.detail ? " (" + c.detail + ")" : ""}`]);
    list("events", (st.events || []).slice().reverse(), (ev) => [ev.level, `${clock(ev.t)} ${ev.text}`]);
    // playback
    const pb = st.playback;
    $("playback").hidden = !pb;
    if (pb) {
      setText("pb-play", pb.paused ? "Play" : "Pause");
      const seek = $("pb-seek");
      if (!S.seeking) seek.value = String(pb.duration > 0 ? Math.round(1000 * pb.position / pb.duration) : 0);
      setText("pb-time", pb.loading ? `reading… ${pb.frames} frames` : `${fmt(pb.position, 1)} / ${fmt(pb.duration, 1)} s`);
      const sp = $("pb-speed");
      if (document.activeElement !== sp) {
        const v = String(pb.speed);
        if (![...sp.options].some((o) => o.value === v)) { const o = document.createElement("option"); o.value = v; o.textContent = `${v}×`; sp.appendChild(o); }
        sp.value = v;
      }
    }
  }
  function list(id, items, render) {
    const ul = $(id);
    const key = JSON.stringify(items.map((x) => [x.seq || x.id, x.status]));
    if (ul.dataset.key === key) return;
    ul.dataset.key = key;
    ul.textContent = "";
    for (const it of items) {
      const [cls, text] = render(it);
      const li = document.createElement("li");
      if (cls) li.className = cls;
      li.textContent = text;
      ul.appendChild(li);
    }
  }

  // --- the update loop ----------------------------------------------------------------------------------
  function draw() {
    S.scheduled = false;
    try {
      drawScene();
      drawPlots();
      drawPanels();
      S.drawn += 1;
    } finally {
      if (S.needAck && S.ws && S.ws.readyState === WebSocket.OPEN) {
        S.needAck = false;
        S.ws.send('{"type":"ack"}');
      }
    }
  }
  function schedule() {
    if (!S.scheduled) { S.scheduled = true; window.requestAnimationFrame(draw); }
  }
  function onUpdate(msg) {
    const st = msg.state;
    if (st.epoch !== S.epoch) { S.epoch = st.epoch; S.history = []; }
    for (const p of msg.history) S.history.push(p);
    if (S.history.length) {
      const tmax = S.history[S.history.length - 1][1];
      let cut = 0;
      while (cut < S.history.length && S.history[cut][1] < tmax - 35) cut++;
      if (cut > 0) S.history.splice(0, cut);
    }
    S.state = st;
    S.updates += 1;
    S.needAck = true;
    schedule();
  }
  function connect() {
    const proto = location.protocol === "https:" ? "wss:" : "ws:";
    const ws = new WebSocket(`${proto}//${location.host}/ws`);
    S.ws = ws;
    ws.onopen = () => {
      S.connected = true; S.retry = 500;
      setText("conn", "connected"); $("conn").className = "pill on";
    };
    ws.onmessage = (ev) => {
      const msg = JSON.parse(ev.data);
      if (msg.type === "hello") { S.hello = msg; buildStatic(); }
      else if (msg.type === "update") onUpdate(msg);
      else if (msg.type === "command" || msg.type === "playback" || msg.type === "error") {
        if (msg.ok === false) note("warning", msg.text || "refused");
      }
    };
    ws.onclose = () => {
      S.connected = false;
      setText("conn", "disconnected: retrying"); $("conn").className = "pill off";
      setTimeout(connect, S.retry);
      S.retry = Math.min(S.retry * 2, 5000);
    };
  }
  function note(level, text) { // a local message in the events list until the next update
    const ul = $("events");
    const li = document.createElement("li");
    li.className = level;
    li.textContent = `${clock(Date.now() / 1000)} ${text}`;
    ul.insertBefore(li, ul.firstChild);
    ul.dataset.key = "";
  }
  function send(obj) { if (S.ws && S.ws.readyState === WebSocket.OPEN) S.ws.send(JSON.stringify(obj)); }

  // --- commands behind a confirmation -------------------------------------------------------------------
  function confirmCommand(name, arg, text) {
    S.pendingCommand = { name, arg };
    const src = (S.state && S.state.source && S.state.source.text) || "the bus";
    setText("modal-text", `${text} on ${src}?`);
    $("modal").hidden = false;
    $("modal-ok").focus();
  }
  function closeModal() { $("modal").hidden = true; S.pendingCommand = null; }

  function wire() {
    $("cmd-reset").addEventListener("click", () => confirmCommand("reset", 0,
      "Reset the node's filter (CMD 2: the attitude is initialised again, steps restart at 0)"));
    $("cmd-select").addEventListener("click", () => {
      const k = $("cmd-kind").value;
      confirmCommand("select", k, `Select the filter ${k} on the node (CMD 1: a fresh filter of that kind)`);
    });
    $("cmd-convention").addEventListener("click", () => {
      const c = $("cmd-conv").value;
      confirmCommand("convention", c, `Set the node's output convention to ${c} (CMD 8, SET_CONVENTION)`);
    });
    $("modal-cancel").addEventListener("click", closeModal);
    $("modal-ok").addEventListener("click", () => {
      const p = S.pendingCommand;
      closeModal();
      if (p) send({ type: "command", name: p.name, arg: p.arg, confirmed: true });
    });
    document.addEventListener("keydown", (ev) => { if (ev.key === "Escape" && !$("modal").hidden) closeModal(); });
    // playback
    $("pb-play").addEventListener("click", () => {
      const pb = S.state && S.state.playback;
      send({ type: "playback", action: pb && pb.paused ? "play" : "pause" });
    });
    const seek = $("pb-seek");
    seek.addEventListener("input", () => { S.seeking = true; });
    seek.addEventListener("change", () => {
      S.seeking = false;
      const pb = S.state && S.state.playback;
      if (pb) send({ type: "playback", action: "seek", value: pb.duration * Number(seek.value) / 1000 });
    });
    $("pb-speed").addEventListener("change", (ev) => send({ type: "playback", action: "speed", value: Number(ev.target.value) }));
    // the camera
    const cv = $("scene");
    let drag = null;
    cv.addEventListener("pointerdown", (ev) => { drag = [ev.clientX, ev.clientY]; cv.setPointerCapture(ev.pointerId); });
    cv.addEventListener("pointermove", (ev) => {
      if (!drag) return;
      S.cam.az -= (ev.clientX - drag[0]) * 0.008;
      S.cam.el = Math.max(-1.4, Math.min(1.5, S.cam.el + (ev.clientY - drag[1]) * 0.008));
      drag = [ev.clientX, ev.clientY];
      schedule();
    });
    cv.addEventListener("pointerup", () => { drag = null; });
    cv.addEventListener("wheel", (ev) => {
      ev.preventDefault();
      S.cam.dist = Math.max(3, Math.min(25, S.cam.dist * Math.exp(ev.deltaY * 0.001)));
      schedule();
    }, { passive: false });
    cv.addEventListener("dblclick", () => { S.cam = Object.assign({}, CAM0); schedule(); });
    window.addEventListener("resize", schedule);
  }

  // what a test (or the console) can read back
  window.atticaView = {
    camera: () => {
      const cv = $("scene");
      const cam = S.lastCam || camera(cv.clientWidth, cv.clientHeight);
      return Object.assign({}, cam, { dpr: window.devicePixelRatio || 1 });
    },
    scene: () => {
      const R = S.qDisp ? qmat(S.qDisp) : null;
      return { q: S.qConv, qDisplay: S.qDisp, R, truth: S.truth, convention: S.state ? S.state.convention : null,
        nose: R ? mv(R, NOSE) : null, noseRgb: NOSE_RGB, noseBody: NOSE };
    },
    state: () => S.state,
    counts: () => ({ updates: S.updates, drawn: S.drawn, history: S.history.length, connected: S.connected }),
    resetCamera: () => { S.cam = Object.assign({}, CAM0); schedule(); },
  };

  wire();
  connect();
}());
