// End-to-end test of `rdslam view` (issue 26) in Debian's headless Chromium through
// playwright-core: a real-time replay publishes over LCM (`rdslam replay --lcm`), `rdslam
// view` serves the page, the browser opens it; the test waits for the camera image and at
// least 10 trajectory points, saves a screenshot in OUT_DIR, and checks that the displayed
// frame counter and processed-frame counter advance and the state is shown. Then the security
// rules: a non-loopback --listen without --token is refused (exit 2), and with a token a
// request without it gets 401, with it 200.
// Usage: node viewer_e2e.mjs RDSLAM_BINARY OUT_DIR CHROMIUM
import { spawn, spawnSync } from "node:child_process";
import { mkdirSync, mkdtempSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { randomInt } from "node:crypto";
import { join } from "node:path";
import { chromium } from "playwright-core";

const [bin, outDir, chromiumPath] = process.argv.slice(2);
if (!bin || !outDir || !chromiumPath) {
  console.error("usage: node viewer_e2e.mjs RDSLAM_BINARY OUT_DIR CHROMIUM");
  process.exit(2);
}
mkdirSync(outDir, { recursive: true });
// A port of its own, drawn at random, so that other tests and other test runs on this host
// (ttl=0 multicast is host-wide, across PID namespaces) do not hear each other.
const lcmPort = 20000 + randomInt(20000);
const lcmUrl = `udpm://239.255.76.67:${lcmPort}?ttl=0`;
const children = [];
let failed = false;

function start(args, name) {
  const p = spawn(bin, args, { stdio: ["ignore", "pipe", "pipe"] });
  p.out = "";
  p.stdout.on("data", (d) => { p.out += d; });
  p.stderr.on("data", (d) => { p.err = (p.err || "") + d; });
  p.name = name;
  children.push(p);
  return p;
}
function check(cond, msg) {
  console.log(`${cond ? "ok  " : "FAIL"} ${msg}`);
  if (!cond) failed = true;
}
async function until(fn, ms, what) {
  const t0 = Date.now();
  for (;;) {
    const v = await fn();
    if (v) return v;
    if (Date.now() - t0 > ms) throw new Error(`timed out after ${ms} ms waiting for ${what}`);
    await new Promise((r) => setTimeout(r, 100));
  }
}
async function viewUrl(p) {
  return until(() => { const m = /http:\/\/\S+/.exec(p.out); return m && m[0]; }, 10000,
    `${p.name} to print its URL`);
}
function cleanup() {
  for (const p of children) if (p.exitCode === null) p.kill("SIGTERM");
}

let browser = null;
const profile = mkdtempSync(join(tmpdir(), "rdslam-e2e-chromium-"));
try {
  const view = start(["view", "--listen", "127.0.0.1:0", "--set", `lcm.url=${lcmUrl}`], "view");
  const url = await viewUrl(view);
  console.log(`view at ${url}, LCM ${lcmUrl}`);
  const replay = start(["replay", "synth:static_xyz", "--realtime", "--lcm", "--set",
    `lcm.url=${lcmUrl}`, "--set", "viewer.image_hz=5", "--set", "pipeline.stats_period_ms=500"],
  "replay");

  // A new empty profile (--user-data-dir, which playwright passes for a persistent context).
  browser = await chromium.launchPersistentContext(profile, {
    executablePath: chromiumPath,
    headless: true,
    args: ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
      "--disable-background-networking", "--disable-component-update", "--disable-sync"],
    viewport: { width: 1400, height: 760 },
  });
  const page = await browser.newPage();
  const external = [];
  page.on("request", (r) => { if (!r.url().startsWith(url.replace(/\/$/, ""))) external.push(r.url()); });
  await page.goto(url);
  await page.waitForFunction(() => {
    const img = document.getElementById("cam");
    return img.complete && img.naturalWidth > 0 &&
      Number(document.getElementById("traj-count").textContent) >= 10;
  }, null, { timeout: 30000 });
  const read = () => page.evaluate(() => ({
    frame: Number(document.getElementById("frame").textContent),
    state: document.getElementById("state").textContent,
    processed: Number(document.getElementById("processed").textContent),
    traj: Number(document.getElementById("traj-count").textContent),
    img: document.getElementById("cam").naturalWidth,
    keyframes: Number(document.getElementById("kfs").textContent),
  }));
  const a = await read();
  await page.waitForTimeout(1500);
  const b = await read();
  console.log(`first ${JSON.stringify(a)}\nlater ${JSON.stringify(b)}`);
  await page.screenshot({ path: join(outDir, "viewer.png") });
  console.log(`screenshot ${join(outDir, "viewer.png")}`);
  check(a.img > 0 && a.img <= 640, `image shown, ${a.img} px wide (<= 640)`);
  check(a.traj >= 10, `${a.traj} trajectory points shown`);
  check(b.frame > a.frame, `frame counter advances (${a.frame} -> ${b.frame})`);
  check(b.processed > a.processed, `processed frames advance (${a.processed} -> ${b.processed})`);
  check(["TRACKING", "RELOCALIZED"].includes(b.state) && a.state !== "-",
    `state shown (${a.state} -> ${b.state})`);
  check(b.traj > a.traj, `trajectory grows (${a.traj} -> ${b.traj})`);
  check(external.length === 0, `no request leaves the viewer's origin (${external.length})`);
  replay.kill("SIGTERM");

  // Security: a non-loopback address needs a token.
  const refused = spawnSync(bin, ["view", "--listen", "0.0.0.0:0", "--set", `lcm.url=${lcmUrl}`],
    { encoding: "utf8", timeout: 10000 });
  check(refused.status === 2 && /token/.test(refused.stderr),
    `non-loopback without --token refused (exit ${refused.status}: ${refused.stderr.trim()})`);
  const guarded = start(["view", "--listen", "0.0.0.0:0", "--token", "s3cret-T0ken",
    "--set", `lcm.url=${lcmUrl}`], "view with token");
  const gurl = new URL(await viewUrl(guarded));
  const base = `http://127.0.0.1:${gurl.port}`;
  const noToken = await fetch(`${base}/api/state`);
  const badToken = await fetch(`${base}/api/state?token=wrong`);
  const withToken = await fetch(`${base}/api/state?token=s3cret-T0ken`);
  const bearer = await fetch(`${base}/`, { headers: { Authorization: "Bearer s3cret-T0ken" } });
  const post = await fetch(`${base}/api/state?token=s3cret-T0ken`, { method: "POST", body: "x" });
  check(noToken.status === 401 && badToken.status === 401,
    `requests without the token rejected (${noToken.status}, ${badToken.status})`);
  check(withToken.status === 200 && bearer.status === 200,
    `requests with the token served (${withToken.status}, ${bearer.status})`);
  check(post.status === 405, `read-only: POST rejected (${post.status})`);
  // Without a token (loopback), a foreign Host header (DNS rebinding) is rejected.
  const vurl = new URL(url);
  const rebind = spawnSync("curl", ["-s", "-o", "/dev/null", "-w", "%{http_code}", "-H",
    "Host: evil.example:80", `http://127.0.0.1:${vurl.port}/api/state`], { encoding: "utf8" });
  if (rebind.status === 0) check(rebind.stdout === "403", `foreign Host rejected (${rebind.stdout})`);
} catch (e) {
  console.log(`FAIL ${e.message}`);
  for (const p of children) if (p.err) console.log(`--- ${p.name} stderr (tail):\n${p.err.slice(-1500)}`);
  failed = true;
} finally {
  if (browser) await browser.close();
  cleanup();
  rmSync(profile, { recursive: true, force: true });
}
console.log(failed ? "viewer e2e: FAILED" : "viewer e2e: passed");
process.exit(failed ? 1 : 0);
