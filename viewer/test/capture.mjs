// Drives the viewer page in headless Chromium (Debian's /usr/bin/chromium, software WebGL through
// SwiftShader) with playwright-core, for tests/web/viewer_browser_test.cpp and the figures in
// docs/viewer.md. Usage:
//   node capture.mjs --url http://127.0.0.1:PORT/ --out DIR [--width W --height H]
//        [--camera CAMERA.json --frame F] [--motion NAME] [--bg r,g,b] [--play-shots]
//        [--measure-seconds S] [--shot] [--query K=V&...] [--settle N] [--timeout-ms T] [--no-ui]
// --camera/--frame: DIR/fixed.png, the page at frame F seen through the kinesplat camera.
// --play-shots:     DIR/play1.png and DIR/play2.png, the playing page at two times (the second
//                   once the motion has moved on at least one frame).
// --measure-seconds: the page's drawing rate over S seconds while playing.
// --shot:           DIR/page.png, the page (default camera, controls shown) once ready.
// --query:          more URL parameters for the --play-shots / --measure-seconds / --shot page.
// --settle:         frames the page draws before it counts as ready (the page's default: 8).
// --no-ui:          hides the page's controls in the playing shots too.
// Writes DIR/result.json (frames shown, frame rate, splat count, WebGL renderer) and prints it.
import { chromium } from "playwright-core";
import { chromiumLaunchOptions } from "./chromium_options.mjs";
import { mkdirSync, readFileSync, writeFileSync } from "node:fs";
import { join } from "node:path";

function parseArgs(argv) {
  const a = { width: 320, height: 480, timeoutMs: 45000, measureSeconds: 0, playShots: false, query: "" };
  for (let i = 2; i < argv.length; ++i) {
    const k = argv[i];
    const v = () => argv[++i];
    if (k === "--url") a.url = v();
    else if (k === "--out") a.out = v();
    else if (k === "--width") a.width = parseInt(v(), 10);
    else if (k === "--height") a.height = parseInt(v(), 10);
    else if (k === "--camera") a.camera = v();
    else if (k === "--frame") a.frame = parseInt(v(), 10);
    else if (k === "--motion") a.motion = v();
    else if (k === "--bg") a.bg = v();
    else if (k === "--play-shots") a.playShots = true;
    else if (k === "--no-ui") a.noUi = true;
    else if (k === "--shot") a.shot = true;
    else if (k === "--query") a.query = v();
    else if (k === "--settle") a.settle = v();
    else if (k === "--measure-seconds") a.measureSeconds = parseFloat(v());
    else if (k === "--timeout-ms") a.timeoutMs = parseInt(v(), 10);
    else throw new Error(`unknown argument ${k}`);
  }
  if (!a.url || !a.out) throw new Error("need --url and --out");
  return a;
}

const args = parseArgs(process.argv);
mkdirSync(args.out, { recursive: true });

const browser = await chromium.launch(chromiumLaunchOptions());

const logs = [];
const result = { url: args.url };

async function openPage(query, width, height) {
  if (args.settle) query.set("settle", args.settle);
  const page = await browser.newPage({ viewport: { width, height }, deviceScaleFactor: 1 });
  page.on("console", (m) => logs.push(`[${m.type()}] ${m.text()}`));
  page.on("pageerror", (e) => logs.push(`[pageerror] ${e.message}`));
  await page.goto(args.url + "?" + query.toString(), { waitUntil: "load" });
  await page.waitForFunction(() => window.kinesplat && (window.kinesplat.ready || window.kinesplat.error), null, {
    timeout: args.timeoutMs,
    polling: 100,
  });
  const error = await page.evaluate(() => window.kinesplat.error);
  if (error) throw new Error("the page failed: " + error);
  return page;
}

async function info(page) {
  return page.evaluate(() => {
    const s = window.kinesplat;
    const gl = document.querySelector("canvas").getContext("webgl2");
    const dbg = gl && gl.getExtension("WEBGL_debug_renderer_info");
    return {
      motion: s.motion,
      frame: s.frame,
      numFrames: s.numFrames,
      numSplats: s.numSplats,
      fps: s.fps,
      totalRendered: s.totalRendered,
      webgl: dbg ? gl.getParameter(dbg.UNMASKED_RENDERER_WEBGL) : "unknown",
      userAgent: navigator.userAgent,
    };
  });
}

try {
  if (args.camera) {
    const cam = JSON.parse(readFileSync(args.camera, "utf8"));
    const q = new URLSearchParams({ ui: "0", frame: String(args.frame ?? 0), camera: JSON.stringify(cam) });
    if (args.motion) q.set("motion", args.motion);
    if (args.bg) q.set("bg", args.bg);
    const page = await openPage(q, cam.width, cam.height);
    await page.locator("canvas").screenshot({ path: join(args.out, "fixed.png") });
    result.fixed = await info(page);
    await page.close();
  }
  if (args.playShots || args.measureSeconds > 0 || args.shot) {
    const q = new URLSearchParams(args.query);
    if (args.noUi) q.set("ui", "0");
    if (args.motion) q.set("motion", args.motion);
    if (args.bg) q.set("bg", args.bg);
    const page = await openPage(q, args.width, args.height);
    if (args.shot) {
      await page.screenshot({ path: join(args.out, "page.png") });
      result.shot = await info(page);
    }
    if (args.playShots) {
      const f1 = await page.evaluate(() => window.kinesplat.frame);
      await page.screenshot({ path: join(args.out, "play1.png") });
      result.play1 = await info(page);
      await page.waitForFunction((f) => window.kinesplat.frame !== f, f1, { timeout: args.timeoutMs, polling: 50 });
      // Two more drawn frames, so the new bones are on screen.
      const n = await page.evaluate(() => window.kinesplat.totalRendered);
      await page.waitForFunction((k) => window.kinesplat.totalRendered >= k + 2, n, { timeout: args.timeoutMs });
      await page.screenshot({ path: join(args.out, "play2.png") });
      result.play2 = await info(page);
    }
    if (args.measureSeconds > 0) {
      const n0 = await page.evaluate(() => window.kinesplat.totalRendered);
      const t0 = Date.now();
      await page.waitForTimeout(1000 * args.measureSeconds);
      const n1 = await page.evaluate(() => window.kinesplat.totalRendered);
      result.measured = { frames: n1 - n0, seconds: (Date.now() - t0) / 1000 };
      result.measured.fps = result.measured.frames / result.measured.seconds;
      await page.screenshot({ path: join(args.out, "measured.png") });
      result.measuredInfo = await info(page);
    }
    await page.close();
  }
} catch (e) {
  result.error = String(e && e.message ? e.message : e);
}
await browser.close();
result.logs = logs;
writeFileSync(join(args.out, "result.json"), JSON.stringify(result, null, 2) + "\n");
console.log(JSON.stringify(result, null, 2));
process.exit(result.error ? 1 : 0);
