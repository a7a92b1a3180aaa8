// Drives the studio page in headless Chromium (Debian's /usr/bin/chromium, software WebGL) with
// playwright-core from viewer/node_modules, for tests/studio/studio_browser_test.cpp and the
// screenshots in docs/studio.md. Usage:
//   node drive.mjs --url http://127.0.0.1:PORT/ --out DIR --phase make|resume
//        [--photo PNG] [--blank PNG] [--big FILE] [--text FILE] [--timeout-ms T]
// --phase make:   refusals (an oversized photo, a non-image, traversal attempts), then the photo
//                 made into an avatar (progress followed to the end, the viewer ready, a download
//                 saved as DIR/download.ply), a photo without a person failing, and one more
//                 upload left running (the test then stops the studio).
// --phase resume: the interrupted avatar shown with its resume button, resumed to the end.
// Writes DIR/result.json (what was seen, with times) and DIR/NN-name.png screenshots.
import { chromiumLaunchOptions } from "../../viewer/test/chromium_options.mjs";
import { mkdirSync, writeFileSync } from "node:fs";
import { join } from "node:path";

const { chromium } = await import(
  new URL("../../viewer/node_modules/playwright-core/index.mjs", import.meta.url).href
);

function parseArgs(argv) {
  const a = { timeoutMs: 120000 };
  for (let i = 2; i < argv.length; ++i) {
    const k = argv[i];
    const v = () => argv[++i];
    if (k === "--url") a.url = v();
    else if (k === "--out") a.out = v();
    else if (k === "--phase") a.phase = v();
    else if (k === "--photo") a.photo = v();
    else if (k === "--blank") a.blank = v();
    else if (k === "--big") a.big = v();
    else if (k === "--text") a.text = v();
    else if (k === "--timeout-ms") a.timeoutMs = parseInt(v(), 10);
    else throw new Error(`unknown argument ${k}`);
  }
  if (!a.url || !a.out || !a.phase) throw new Error("need --url, --out and --phase");
  return a;
}

const args = parseArgs(process.argv);
mkdirSync(args.out, { recursive: true });
const t0 = Date.now();
const result = { phase: args.phase, steps: [], logs: [] };
const step = (name, data = {}) => result.steps.push({ name, t: (Date.now() - t0) / 1000, ...data });

const browser = await chromium.launch(chromiumLaunchOptions());
const context = await browser.newContext({ viewport: { width: 1180, height: 860 }, deviceScaleFactor: 1, acceptDownloads: true });
const page = await context.newPage();
page.on("console", (m) => result.logs.push(`[${m.type()}] ${m.text()}`));
page.on("pageerror", (e) => result.logs.push(`[pageerror] ${e.message}`));
let shots = 0;
async function shot(name, fullPage = false) {
  const file = `${String(++shots).padStart(2, "0")}-${name}.png`;
  await page.screenshot({ path: join(args.out, file), fullPage });
  step(`screenshot ${file}`);
}
const studio = () => page.evaluate(() => window.studio);
const selected = () =>
  page.evaluate(() => {
    const s = window.studio;
    return s.state?.avatars.find((a) => a.id === s.selected) || null;
  });
async function waitMessage(pred, what) {
  await page.waitForFunction(pred, null, { timeout: 20000, polling: 50 });
  const s = await studio();
  step(what, { message: s.message, kind: s.messageKind });
  return s.message;
}
// Waits for the selected avatar to reach `state`, noting the progress seen on the way.
async function waitState(state, seen) {
  const end = Date.now() + args.timeoutMs;
  for (;;) {
    const a = await selected();
    if (a && seen && a.progress)
      seen.push({ t: (Date.now() - t0) / 1000, state: a.state, stage: a.progress.stage, percent: a.progress.percent, remaining: a.progress.remaining });
    if (a && a.state === state) return a;
    if (a && state !== "failed" && a.state === "failed") throw new Error(`the avatar failed: ${a.error} (${a.error_stage})`);
    if (Date.now() > end) throw new Error(`timed out waiting for "${state}" (last: ${a && a.state})`);
    await page.waitForTimeout(100);
  }
}
async function viewerReady() {
  await page.waitForFunction(() => document.getElementById("viewer").src.includes("/web/"), null, { timeout: 20000 });
  const frame = () => page.frames().find((f) => f.url().includes("/web/"));
  await page.waitForFunction(() => true); // let the frame attach
  for (let i = 0; i < 200 && !frame(); ++i) await page.waitForTimeout(50);
  const f = frame();
  await f.waitForFunction(() => window.kinesplat && (window.kinesplat.ready || window.kinesplat.error), null, { timeout: 60000, polling: 100 });
  const k = await f.evaluate(() => ({ ready: window.kinesplat.ready, error: window.kinesplat.error, numSplats: window.kinesplat.numSplats, motion: window.kinesplat.motion }));
  if (k.error) throw new Error("the viewer failed: " + k.error);
  return k;
}

try {
  await page.goto(args.url, { waitUntil: "load" });
  await page.waitForFunction(() => window.studio && window.studio.state, null, { timeout: 20000 });
  if (args.phase === "make") {
    result.initialAvatars = (await studio()).state.avatars.length;
    await shot("empty");

    // Refusals. An oversized photo: the page knows the limit and refuses it without sending it;
    // the server refuses it too, by its Content-Length, when a page sends it anyway.
    await page.setInputFiles("#file", args.big);
    result.tooBig = await waitMessage(() => /refused/.test(window.studio.message), "too big (page)");
    await shot("refused-size");
    result.tooBigServer = await page.evaluate(async () => {
      const body = new Blob([new Uint8Array(51 * 1024 * 1024)]);
      try {
        const r = await fetch("/api/avatars", { method: "POST", body, headers: { "X-Filename": "big.png" } });
        return { status: r.status, body: await r.text() };
      } catch (e) {
        return { status: 0, body: String(e) };
      }
    });
    step("too big (server)", result.tooBigServer);
    // Not an image, whatever its name says.
    await page.setInputFiles("#file", args.text);
    result.notImage = await waitMessage(() => /not a PNG or JPEG/.test(window.studio.message), "not an image");
    await shot("refused-type");
    // Ways out of the workspace, as a page (or anything else) could ask.
    result.traversal = await page.evaluate(async () => {
      const out = [];
      for (const t of [
        "/static/%2e%2e/%2e%2e/%2e%2e/etc/passwd",
        "/static/..%2f..%2f..%2fetc%2fpasswd",
        "/api/avatars/..%2f..%2f..%2fetc/files/photo",
        "/avatars/%2e%2e/web/index.html",
      ]) {
        const r = await fetch(t);
        out.push({ target: t, status: r.status, body: (await r.text()).slice(0, 200) });
      }
      return out;
    });
    step("traversal", { traversal: result.traversal });

    // The photo, made into an avatar.
    await page.setInputFiles("#file", args.photo);
    await waitMessage(() => /uploaded/.test(window.studio.message), "uploaded");
    const progress = [];
    // A screenshot while it runs, once reconstruct (the long stage) is a fifth done.
    const end = Date.now() + args.timeoutMs;
    for (;;) {
      const a = await selected();
      if (a && a.progress) progress.push({ t: (Date.now() - t0) / 1000, state: a.state, stage: a.progress.stage, percent: a.progress.percent, remaining: a.progress.remaining });
      const rec = a?.progress?.stages?.find((st) => st.name === "reconstruct");
      if (a && (a.state === "done" || (a.state === "running" && (["videos", "export"].includes(a.progress.stage) || rec?.percent >= 20)))) break;
      if (a && a.state === "failed") throw new Error(`the avatar failed: ${a.error}`);
      if (Date.now() > end) throw new Error("timed out waiting for reconstruct");
      await page.waitForTimeout(100);
    }
    if ((await selected()).state === "running") await shot("progress");
    const made = await waitState("done", progress);
    result.progress = progress;
    result.made = { id: made.id, seconds: made.seconds, stages: made.create?.stages, downloads: made.downloads, videos: made.videos };
    step("made", { id: made.id });
    result.viewer = await viewerReady();
    step("viewer ready", result.viewer);
    await page.waitForTimeout(1500); // a few more frames drawn
    await shot("made", true);
    // The viewer stops drawing (software WebGL would keep both cores busy for the rest).
    await page.evaluate(() => (document.getElementById("viewer").src = "about:blank"));
    // A download, through the page's link.
    const [download] = await Promise.all([page.waitForEvent("download"), page.click('#downloads a[data-name="avatar.ply"]')]);
    await download.saveAs(join(args.out, "download.ply"));
    result.download = { suggested: download.suggestedFilename() };
    step("downloaded", result.download);

    // A photo without a person: create fails, the page shows its error line and stage.
    await page.setInputFiles("#file", args.blank);
    await waitMessage(() => /uploaded/.test(window.studio.message), "uploaded blank");
    const failed = await waitState("failed");
    result.failed = { error: failed.error, stage: failed.error_stage };
    await page.waitForFunction(() => !document.getElementById("failure").hidden && !document.getElementById("resume").hidden);
    result.failedShown = await page.evaluate(() => ({ title: document.getElementById("failure-title").textContent, line: document.getElementById("failure-line").textContent }));
    step("failed", result.failedShown);
    await shot("failed");

    // One more, left running: the test stops the studio now.
    await page.setInputFiles("#file", args.photo);
    await waitMessage(() => /uploaded/.test(window.studio.message), "uploaded again");
    const again = await selected();
    result.left = { id: again.id };
    // Stopped once perceive and fit are made (resume then skips them).
    const end2 = Date.now() + args.timeoutMs;
    for (;;) {
      const a = await selected();
      if (a && a.state === "running" && !["", "perceive", "fit"].includes(a.progress?.stage || "")) break;
      if (a && a.state === "done") throw new Error("the last create ended before the studio was stopped");
      if (Date.now() > end2) throw new Error("timed out waiting for the last create's sample stage");
      await page.waitForTimeout(50);
    }
    step("left running", result.left);
  } else if (args.phase === "resume") {
    const s = await studio();
    result.states = s.state.avatars.map((a) => ({ id: a.id, state: a.state, stage: a.error_stage }));
    await page.waitForFunction(() => !document.getElementById("resume").hidden, null, { timeout: 20000 });
    const a = await selected();
    result.interrupted = { id: a.id, state: a.state, stage: a.error_stage, title: await page.evaluate(() => document.getElementById("failure-title").textContent) };
    step("interrupted", result.interrupted);
    await shot("interrupted");
    await page.click("#resume");
    const progress = [];
    const done = await waitState("done", progress);
    result.progress = progress;
    result.resumed = { id: done.id, stages: done.create?.stages };
    step("resumed", { id: done.id });
  } else {
    throw new Error(`unknown phase ${args.phase}`);
  }
} catch (e) {
  result.error = String(e && e.stack ? e.stack : e);
  try {
    await shot("error");
  } catch {}
}
await browser.close();
result.seconds = (Date.now() - t0) / 1000;
writeFileSync(join(args.out, "result.json"), JSON.stringify(result, null, 2) + "\n");
console.log(JSON.stringify({ phase: result.phase, error: result.error, seconds: result.seconds }));
process.exit(result.error ? 1 : 0);
