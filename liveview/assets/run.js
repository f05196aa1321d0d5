// The run page: polls state.json (every 0.5 s while the run goes) and redraws. Polling
// rather than a stream means a reload, a dropped connection or a server restart simply
// resumes at the next poll.
"use strict";

const $ = (id) => document.getElementById(id);
const colors = ["#d9534f", "#2b7bb9", "#222", "#3a9a4a"];
let forcePlot = null, curvePlot = null, settlePlot = null;
let spans = [];
let lastFrame = null, frameBusy = false, frameAt = 0;
let live = true;

function duration(s) {
  if (!isFinite(s)) return "–";
  s = Math.max(0, s);
  const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), r = Math.round(s % 60);
  return h ? `${h} h ${String(m).padStart(2, "0")} min` : m ? `${m} min ${String(r).padStart(2, "0")} s` : `${(s).toFixed(s < 10 ? 1 : 0)} s`;
}

function width(el) {
  return Math.max(300, el.clientWidth || 600);
}

// Steps shaded behind the force plot, alternately, labelled with their number.
function shadeSteps(u) {
  const ctx = u.ctx, { left, top, width: w, height: h } = u.bbox;
  ctx.save();
  ctx.beginPath();
  ctx.rect(left, top, w, h);
  ctx.clip();
  for (const s of spans) {
    const x0 = u.valToPos(s.t0_s, "x", true), x1 = u.valToPos(s.t1_s, "x", true);
    if (x1 < left || x0 > left + w) continue;
    ctx.fillStyle = s.step % 2 ? "rgba(43,123,185,0.08)" : "rgba(43,123,185,0.16)";
    ctx.fillRect(x0, top, Math.max(1, x1 - x0), h);
    if (x1 - x0 > 18) {
      ctx.fillStyle = "rgba(29,35,48,0.55)";
      ctx.font = `${10 * devicePixelRatio}px sans-serif`;
      ctx.fillText(String(s.step), x0 + 2, top + 12 * devicePixelRatio);
    }
  }
  ctx.restore();
}

function makeForcePlot() {
  const el = $("force");
  return new uPlot({
    width: width(el), height: 300,
    scales: { x: { time: false }, tz: {} },
    axes: [
      { label: "run time (s)" },
      { label: "force (N)" },
      { scale: "tz", side: 1, label: "torque (N·mm)", grid: { show: false } },
    ],
    series: [
      {},
      { label: "Fx (N)", stroke: colors[0] },
      { label: "Fy (N)", stroke: colors[1] },
      { label: "Fz (N)", stroke: colors[2], width: 1.5 },
      { label: "Tz (N·mm)", stroke: colors[3], scale: "tz" },
      { label: "Fz max", stroke: "rgba(34,34,34,0.25)", width: 0.5 },
      { label: "Fz min", stroke: "rgba(34,34,34,0.25)", width: 0.5 },
    ],
    bands: [{ series: [5, 6], fill: "rgba(34,34,34,0.08)" }],
    hooks: { drawClear: [shadeSteps] },
  }, [[], [], [], [], [], [], []], el);
}

function makeCurvePlot() {
  const el = $("curve");
  return new uPlot({
    width: width(el), height: 260,
    mode: 1,
    scales: { x: { time: false } },
    axes: [{ label: "position" }, { label: "Fz (N)" }],
    series: [
      {},
      { label: "Fz at each settled step", stroke: colors[2], points: { show: true, size: 7 } },
    ],
  }, [[], []], el);
}

function makeSettlePlot() {
  const el = $("settle");
  return new uPlot({
    width: width(el), height: 200,
    scales: { x: { time: false }, y: { distr: 3 } },
    axes: [{ label: "s since the settle began" }, { label: "drift bound" }],
    series: [
      {},
      { label: "statistic", stroke: "#2b7bb9" },
      { label: "threshold", stroke: "#c93838", dash: [6, 4] },
    ],
  }, [[], [], []], el);
}

function bar(label, fraction) {
  const pct = Math.max(0, Math.min(1, fraction)) * 100;
  const cls = fraction < 0.1 ? "bad" : fraction < 0.3 ? "warn" : "";
  return `<div>${label}</div><div class="bar"><i class="${cls}" style="width:${pct.toFixed(1)}%"></i><span>${(fraction * 100).toFixed(1)} % of the limit left</span></div>`;
}

function render(s) {
  live = s.meta.live;
  document.title = `gelrig · ${s.meta.protocol}`;
  $("title").textContent = `${s.meta.protocol} on ${s.meta.rig}`;
  const badge = $("status");
  badge.textContent = s.status;
  badge.className = "badge " + s.status;
  $("report-link").hidden = live && s.status === "running";
  const counter = $("step-counter");
  counter.textContent = `${s.steps_done}/${s.meta.steps_planned}` + (s.step ? ` (step ${s.step}${s.trial ? `, trial ${s.trial}` : ""} under way)` : "");
  counter.dataset.stepsDone = s.steps_done;
  $("what").textContent = s.what || "–";
  $("phase").textContent = s.phase;
  $("t").textContent = duration(s.t_s);
  const k = s.meta.time_scale;
  $("left").textContent = s.status !== "running" ? "–"
    : duration(s.left_s) + (k && Math.abs(k - 1) > 1e-9 ? ` (~${duration(s.left_s / k)} wall at ×${k})` : k ? "" : " (virtual)");

  // Force history.
  spans = s.spans;
  const f = s.force;
  forcePlot = forcePlot || makeForcePlot();
  forcePlot.setData([f.t_s, f.mean[0], f.mean[1], f.mean[2], f.mean[3], f.max[2], f.min[2]]);
  $("force").dataset.points = f.samples;
  $("force-info").textContent = `${f.samples} readings` + (f.bucket_s > 0.0051 ? `, ${f.t_s.length} buckets of ${f.bucket_s.toFixed(2)} s (mean, Fz min–max band)` : "");

  // Force against position.
  curvePlot = curvePlot || makeCurvePlot();
  const pts = s.curve.filter((p) => p.axis === (s.curve[s.curve.length - 1] || {}).axis);
  const order = pts.map((p, i) => i).sort((a, b) => pts[a].position - pts[b].position);
  curvePlot.setData([order.map((i) => pts[i].position), order.map((i) => pts[i].wrench[2])]);
  $("curve").dataset.points = pts.length;
  if (pts.length) curvePlot.axes[0].label = `${pts[0].axis} position (${pts[0].unit})`;

  // Settling.
  settlePlot = settlePlot || makeSettlePlot();
  if (s.settle) {
    const tr = s.settle.trace;
    settlePlot.setData([tr.map((p) => p[0]), tr.map((p) => Math.max(p[1], 1e-9)), tr.map(() => s.settle.below)]);
    $("settle-info").textContent = `step ${s.settle.step}: ${s.settle.bound.toPrecision(3)} ${s.settle.unit} against ${s.settle.below} ${s.settle.unit}` + (s.settle.bound < s.settle.below ? " — below" : "");
  } else {
    $("settle-info").textContent = "no step is settling on a rate rule now";
  }

  // Margins and counters.
  const m = s.margins;
  $("margins").innerHTML = m
    ? bar(`|Fz| ≤ ${s.meta.max_fz_n} N`, m[0]) + bar(`|Fxy| ≤ ${s.meta.max_fxy_n} N`, m[1]) + bar(`|Tz| ≤ ${s.meta.max_tz_nmm} N·mm`, m[2])
    : "<p class='note'>no force reading yet</p>";
  $("counters").innerHTML =
    `<tr><td>force readings</td><td id="n-force">${f.samples}</td></tr>` +
    `<tr><td>force records lost</td><td id="n-lost">${s.lost_records ?? "not known for a recorded run"}</td></tr>` +
    `<tr><td>frames recorded</td><td id="n-frames">${s.frames}</td></tr>` +
    `<tr><td>frames dropped</td><td id="n-dropped">${s.frames_dropped}</td></tr>`;
  const t = s.tactile;
  const tac = $("tactile");
  if (t) {
    tac.textContent = `${t.state}${t.gripping ? `, ${(t.stuck_fraction * 100).toFixed(0)} % of the contact stuck` : ", grip open"}` +
      (t.gelsight_fz_n != null ? ` · GelSight Fz ${t.gelsight_fz_n.toFixed(2)} N` : "") + ` (at ${duration(t.t_s)})`;
    tac.dataset.state = t.state;
  }
  $("notes").innerHTML = "";
  for (const line of s.notes.slice().reverse()) {
    const li = document.createElement("li");
    li.textContent = line;
    $("notes").appendChild(li);
  }
  if (s.message) {
    const li = document.createElement("li");
    li.textContent = `run ${s.status}: ${s.message}`;
    $("notes").prepend(li);
  }
  if (s.frame_index != null && s.frame_index !== lastFrame) showFrame(s.frame_index);
}

// The latest frame, at most once a second, with its arrows and contact outline.
async function showFrame(index) {
  const now = performance.now();
  if (frameBusy || now - frameAt < 1000) return;
  frameBusy = true;
  frameAt = now;
  try {
    const img = new Image();
    const loaded = new Promise((ok, fail) => { img.onload = ok; img.onerror = fail; });
    img.src = `frame.png?i=${index}`;
    await loaded;
    const r = await fetch(`overlay.json?i=${index}`, { cache: "no-store" });
    const o = r.ok ? await r.json() : { arrows: [], outline: [], note: await r.text() };
    const c = $("frame");
    c.width = img.naturalWidth;
    c.height = img.naturalHeight;
    const ctx = c.getContext("2d");
    ctx.drawImage(img, 0, 0);
    const gain = Number($("gain").value);
    ctx.strokeStyle = "#ffdd00";
    ctx.lineWidth = 1.5;
    for (const [x, y, dx, dy] of o.arrows) {
      const ex = x + gain * dx, ey = y + gain * dy;
      ctx.beginPath();
      ctx.moveTo(x, y);
      ctx.lineTo(ex, ey);
      const a = Math.atan2(ey - y, ex - x), l = Math.min(5, Math.hypot(ex - x, ey - y) / 2);
      ctx.lineTo(ex - l * Math.cos(a - 0.5), ey - l * Math.sin(a - 0.5));
      ctx.moveTo(ex, ey);
      ctx.lineTo(ex - l * Math.cos(a + 0.5), ey - l * Math.sin(a + 0.5));
      ctx.stroke();
    }
    if (o.outline.length > 2) {
      ctx.strokeStyle = "#ff3b8d";
      ctx.lineWidth = 2;
      ctx.beginPath();
      o.outline.forEach(([x, y], i) => (i ? ctx.lineTo(x, y) : ctx.moveTo(x, y)));
      ctx.closePath();
      ctx.stroke();
    }
    c.dataset.arrows = o.arrows.length;
    $("frame-info").textContent = `frame ${index}: ${o.arrows.length} markers` + (o.outline.length ? ", contact outlined" : "");
    $("overlay-note").textContent = o.note || "";
    lastFrame = index;
  } catch (e) {
    $("overlay-note").textContent = "frame not shown: " + (e.message || "could not load it");
  } finally {
    frameBusy = false;
  }
}

async function poll() {
  const conn = $("conn");
  try {
    const r = await fetch("state.json", { cache: "no-store" });
    if (!r.ok) throw new Error(`${r.status} ${await r.text()}`);
    render(await r.json());
    conn.textContent = live ? "live · updated " + new Date().toLocaleTimeString() : "recorded run";
    conn.className = "conn ok";
  } catch (e) {
    conn.textContent = live ? "connection lost — retrying (the run goes on; `gelrig view` shows it after)" : "cannot read the run: " + e.message;
    conn.className = "conn lost";
  }
  setTimeout(poll, live ? 500 : 5000);
}

window.addEventListener("resize", () => {
  for (const [p, id] of [[forcePlot, "force"], [curvePlot, "curve"], [settlePlot, "settle"]])
    if (p) p.setSize({ width: width($(id)), height: p.height });
});
$("gain").addEventListener("change", () => { lastFrame = null; frameAt = 0; });
poll();
