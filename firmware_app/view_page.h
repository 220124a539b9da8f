// The single page `rdslam view` serves (firmware_app/cmd_view.cpp, docs/viewer.md): plain
// HTML, CSS and JavaScript written for rdslam, embedded in the binary so that nothing loads
// from elsewhere at run time (the page's Content-Security-Policy allows its own origin only).
// It polls /api/state (JSON, 5 Hz: pose, status, new trajectory points), reloads
// /api/image.jpg when a new image arrived and /api/map when a new map arrived, and draws the
// trajectory, keyframes and map points in a canvas with a small perspective projection:
// drag to orbit, wheel to zoom, shift+drag to pan, double-click to fit again (the view follows the
// map until moved). Read-only: the page sends no commands. A token given to `rdslam view --token`
// is taken from the page's own URL
// (?token=...) and sent with every request.
//
// Threads: a constant; read by the HTTP thread.
#pragma once

namespace rdslam {

inline const char* view_page_html() {
  return R"PAGE(<!doctype html>
<html lang="en"><head><meta charset="utf-8">
<title>rdslam view</title>
<meta name="viewport" content="width=device-width, initial-scale=1">
<style>
body{margin:0;background:#181a1f;color:#d8dde6;font:14px/1.35 system-ui,sans-serif}
header{display:flex;flex-wrap:wrap;gap:6px 18px;padding:8px 12px;background:#22252c;align-items:baseline}
header h1{font-size:16px;margin:0 8px 0 0;color:#fff}
.kv b{color:#fff;font-variant-numeric:tabular-nums}
#state{padding:1px 8px;border-radius:4px;background:#555;color:#fff;font-weight:bold}
#state.TRACKING{background:#1c8a2e}#state.LOST{background:#b3261e}#state.RELOCALIZED{background:#2a6fb0}
#state.INITIALIZING{background:#777}
main{display:flex;flex-wrap:wrap;gap:10px;padding:10px}
.panel{background:#111317;border:1px solid #333;border-radius:4px}
#cam{display:block;max-width:640px;width:100%;min-width:320px;background:#000}
#camwrap{flex:0 1 640px}
#viewwrap{flex:1 1 480px;min-width:360px}
#view{display:block;width:100%;height:480px;cursor:grab}
.note{color:#8a93a3;font-size:12px;padding:4px 8px}
#stale{color:#f0b429}
</style></head>
<body>
<header>
<h1>rdslam</h1>
<span class="kv">state <span id="state">-</span></span>
<span class="kv">frame <b id="frame">-</b></span>
<span class="kv">fps <b id="fps">-</b></span>
<span class="kv">latency p50/p99 <b id="latency">-</b> ms</span>
<span class="kv">tracker p50/p99 <b id="tracker">-</b> ms</span>
<span class="kv">processed <b id="processed">-</b></span>
<span class="kv">dropped <b id="dropped">-</b></span>
<span class="kv">inliers <b id="inliers">-</b></span>
<span class="kv">map <b id="mappts">-</b> points, <b id="kfs">-</b> keyframes</span>
<span class="kv">invalidated <b id="invalid">-</b></span>
<span class="kv">trajectory <b id="traj-count">0</b> poses</span>
<span id="stale"></span>
</header>
<main>
<div id="camwrap" class="panel"><img id="cam" alt="no image yet (viewer.image_hz)">
<div class="note">annotated camera image: inliers green, rejected matches orange/magenta, map points cyan, invalidated points red; image <span id="imgseq">-</span></div></div>
<div id="viewwrap" class="panel"><canvas id="view" width="800" height="480"></canvas>
<div class="note">trajectory orange, keyframes white, map points cyan (invalidated red), camera green; drag: orbit, wheel: zoom, shift+drag: pan, double-click: fit. Map <span id="mapinfo">-</span></div></div>
</main>
<script>
"use strict";
const token = new URLSearchParams(location.search).get("token");
function api(path, extra) {
  const q = new URLSearchParams(extra || {});
  if (token) q.set("token", token);
  const s = q.toString();
  return path + (s ? "?" + s : "");
}
const $ = (id) => document.getElementById(id);
let traj = [];          // flat x, y, z of tracked poses (world)
let trajGen = -1;
let map = {kf: [], pts: [], valid: []};
let mapVersion = -1, imageSeq = -1, cur = null, fitVersion = "";
let view = {yaw: 0.35, pitch: 0.45, dist: 5, tx: 0, ty: 0, tz: 0, user: false};
function fmt(v, d) { return (v === null || v === undefined) ? "-" : Number(v).toFixed(d); }

async function poll() {
  try {
    const r = await fetch(api("/api/state", {traj_from: traj.length / 3, gen: trajGen}), {cache: "no-store"});
    if (!r.ok) throw new Error("HTTP " + r.status);
    const s = await r.json();
    if (s.traj_gen !== trajGen) { traj = []; trajGen = s.traj_gen; }
    if (s.traj_from === traj.length / 3) for (const v of s.traj) traj.push(v);
    $("traj-count").textContent = traj.length / 3;
    if (s.pose) {
      cur = s.pose;
      $("state").textContent = s.pose.state; $("state").className = s.pose.state;
      $("frame").textContent = s.pose.seq;
      $("inliers").textContent = s.pose.inliers;
    }
    if (s.status) {
      const t = s.status;
      $("fps").textContent = fmt(t.fps, 1);
      $("latency").textContent = fmt(t.latency_p50_ms, 1) + " / " + fmt(t.latency_p99_ms, 1);
      $("tracker").textContent = fmt(t.tracker_p50_ms, 1) + " / " + fmt(t.tracker_p99_ms, 1);
      $("processed").textContent = t.frames_processed;
      $("dropped").textContent = t.frames_dropped;
      $("mappts").textContent = t.map_points; $("kfs").textContent = t.keyframes;
      $("invalid").textContent = t.invalidated_points;
    }
    $("stale").textContent = s.last_message_age_s === null ? "waiting for rdslam on " + s.lcm_url :
      (s.last_message_age_s > 3 ? "no message for " + fmt(s.last_message_age_s, 0) + " s" : "");
    if (s.image_seq !== imageSeq && s.image_seq >= 0) {
      imageSeq = s.image_seq;
      $("cam").src = api("/api/image.jpg", {n: imageSeq});
      $("imgseq").textContent = "#" + imageSeq + " (frame " + s.image_frame + ")";
    }
    if (s.map_version !== mapVersion && s.map_version >= 0) {
      const m = await fetch(api("/api/map"), {cache: "no-store"});
      if (m.ok) {
        map = await m.json(); mapVersion = map.version;
        $("mapinfo").textContent = "frame " + map.seq + ": " + map.valid.length + " of " + map.total_points + " points sent, " + map.kf.length / 3 + " keyframes";
      }
    }
    draw();
  } catch (e) {
    $("stale").textContent = "viewer unreachable: " + e.message;
  }
  setTimeout(poll, 200);
}

function fit() {
  // Bounds of the trajectory, the keyframes and the middle 90% of the map points per axis.
  const all = traj.concat(map.kf);
  let lo = [1e30, 1e30, 1e30], hi = [-1e30, -1e30, -1e30];
  for (let i = 0; i < all.length; i += 3) for (let k = 0; k < 3; ++k) {
    lo[k] = Math.min(lo[k], all[i + k]); hi[k] = Math.max(hi[k], all[i + k]);
  }
  const n = map.pts.length / 3;
  if (n >= 20) for (let k = 0; k < 3; ++k) {
    const v = [];
    for (let i = 0; i < n; ++i) v.push(map.pts[3 * i + k]);
    v.sort((a, b) => a - b);
    lo[k] = Math.min(lo[k], v[Math.floor(0.05 * (n - 1))]);
    hi[k] = Math.max(hi[k], v[Math.ceil(0.95 * (n - 1))]);
  }
  if (lo[0] > hi[0]) return;
  view.tx = (lo[0] + hi[0]) / 2; view.ty = (lo[1] + hi[1]) / 2; view.tz = (lo[2] + hi[2]) / 2;
  const ext = Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 0.5);
  view.dist = 1.6 * ext;
}

// World (camera frame of the first keyframe: x right, y down, z forward) to canvas pixels.
function projector(cv) {
  const W = cv.width, H = cv.height, f = 0.9 * Math.min(W, H);
  const cy = Math.cos(view.yaw), sy = Math.sin(view.yaw), cp = Math.cos(view.pitch), sp = Math.sin(view.pitch);
  return (x, y, z) => {
    const X = x - view.tx, Y = -(y - view.ty), Z = z - view.tz;   // up = -y
    const xr = cy * X - sy * Z, zr = sy * X + cy * Z;
    const yr = cp * Y - sp * zr, zr2 = sp * Y + cp * zr;
    const d = view.dist + zr2;
    if (d < 1e-3) return null;
    return [W / 2 + f * xr / d, H / 2 - f * yr / d];
  };
}

function draw() {
  const cv = $("view"), g = cv.getContext("2d");
  const w = cv.clientWidth | 0, h = cv.clientHeight | 0;
  if (w > 0 && (cv.width !== w || cv.height !== h)) { cv.width = w; cv.height = h; }
  if (!view.user && fitVersion !== mapVersion + ":" + traj.length) {  // follows the map until moved
    fit(); fitVersion = mapVersion + ":" + traj.length;
  }
  g.fillStyle = "#0d0f12"; g.fillRect(0, 0, cv.width, cv.height);
  const P = projector(cv);
  for (let i = 0, n = map.valid.length; i < n; ++i) {
    const q = P(map.pts[3 * i], map.pts[3 * i + 1], map.pts[3 * i + 2]);
    if (!q) continue;
    g.fillStyle = map.valid[i] ? "#5fd3e6" : "#ff3b30";
    g.fillRect(q[0] - 1, q[1] - 1, map.valid[i] ? 2 : 3, map.valid[i] ? 2 : 3);
  }
  g.fillStyle = "#ffffff";
  for (let i = 0; i < map.kf.length; i += 3) {
    const q = P(map.kf[i], map.kf[i + 1], map.kf[i + 2]);
    if (q) g.fillRect(q[0] - 3, q[1] - 3, 6, 6);
  }
  g.strokeStyle = "#ff9f1a"; g.lineWidth = 2; g.beginPath();
  let pen = false;
  for (let i = 0; i < traj.length; i += 3) {
    const q = P(traj[i], traj[i + 1], traj[i + 2]);
    if (!q) { pen = false; continue; }
    if (pen) g.lineTo(q[0], q[1]); else g.moveTo(q[0], q[1]);
    pen = true;
  }
  g.stroke();
  if (cur && cur.position) {
    const q = P(cur.position[0], cur.position[1], cur.position[2]);
    if (q) { g.fillStyle = "#39d353"; g.beginPath(); g.arc(q[0], q[1], 6, 0, 2 * Math.PI); g.fill(); }
  }
}

(function controls() {
  const cv = $("view");
  let drag = null;
  cv.addEventListener("mousedown", (e) => { drag = {x: e.clientX, y: e.clientY, pan: e.shiftKey}; cv.style.cursor = "grabbing"; });
  window.addEventListener("mouseup", () => { drag = null; cv.style.cursor = "grab"; });
  window.addEventListener("mousemove", (e) => {
    if (!drag) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    drag.x = e.clientX; drag.y = e.clientY;
    if (drag.pan) {
      const s = view.dist / 600, cy = Math.cos(view.yaw), sy = Math.sin(view.yaw);
      view.tx -= s * dx * cy; view.tz += s * dx * sy; view.ty += s * dy;
    } else {
      view.yaw += dx * 0.01;
      view.pitch = Math.max(-1.55, Math.min(1.55, view.pitch + dy * 0.01));
    }
    view.user = true; draw();
  });
  cv.addEventListener("wheel", (e) => { e.preventDefault(); view.dist *= Math.exp(e.deltaY * 0.001); view.user = true; draw(); }, {passive: false});
  cv.addEventListener("dblclick", () => { view.user = false; fit(); draw(); });
})();
poll();
</script>
</body></html>
)PAGE";
}

}  // namespace rdslam
