// kinesplat's glTF export in a browser: three.js renders the skinned mesh posed at one frame of a
// named animation, Babylon.js loads the Gaussians through its KHR_gaussian_splatting extension
// and renders them at rest, both in headless Chromium (Debian's /usr/bin/chromium, software WebGL
// through SwiftShader, launched as viewer/test/capture.mjs does) with playwright-core, through a
// kinesplat camera. For tests/gltf/browser_test.cpp and the figures in docs/export.md.
//
// Usage: node render.mjs --glb FILE.glb --out DIR --camera CAMERA.json [--bg r,g,b]
//          [--three] [--babylon] [--clip NAME --frame F] [--babylon-camera CAMERA.json]
//          [--babylon-pose] [--babylon-no-render] [--timeout-ms T]
//   --camera       a kinesplat camera (core/camera.hpp's JSON: width, height, fx, fy, cx, cy, R, t;
//                  OpenCV pinhole, world to camera); the images are exactly width x height
//   --bg           the background (display sRGB, 0..1; default 0,0,0)
//   --three        DIR/three.png: the mesh `avatar_mesh` alone (the splat points hidden), unlit in
//                  its own colour, posed by AnimationMixer at time F / fps of animation NAME (fps
//                  from the animation's extras; without --clip, at rest)
//   --babylon      Babylon's load of the GLB (what it made) and DIR/babylon.png, the splats alone at
//                  rest (no animation); --babylon-no-render: the load only
//   --babylon-camera  Babylon's camera (default: --camera's)
//   --babylon-pose also DIR/babylon_posed.png, the splats after the animation group NAME went to
//                  frame F, and DIR/babylon_posed_mesh.png, the skinned mesh alone so posed
// Neither --three nor --babylon: both. KS_CHROMIUM overrides the browser.
// Prints one JSON line (renderer, counts, file paths, timings) and writes it to DIR/result.json;
// exits 1 with a message on stderr (and "error" in the JSON) on any failure.
import { chromium } from "playwright-core";
import { chromiumLaunchOptions } from "../../../viewer/test/chromium_options.mjs";
import { createServer } from "node:http";
import { mkdirSync, readFileSync, statSync, writeFileSync, createReadStream } from "node:fs";
import { dirname, extname, join, normalize, resolve, sep } from "node:path";
import { fileURLToPath } from "node:url";

const here = dirname(fileURLToPath(import.meta.url));
const tStart = performance.now();

function parseArgs(argv) {
  const a = { bg: [0, 0, 0], timeoutMs: 60000, three: false, babylon: false, babylonPose: false, babylonRender: true };
  for (let i = 2; i < argv.length; ++i) {
    const k = argv[i];
    const v = () => {
      if (i + 1 >= argv.length) throw new Error(`${k} needs a value`);
      return argv[++i];
    };
    if (k === "--glb") a.glb = v();
    else if (k === "--out") a.out = v();
    else if (k === "--camera") a.camera = v();
    else if (k === "--babylon-camera") a.babylonCamera = v();
    else if (k === "--bg") {
      a.bg = v().split(",").map(Number);
      if (a.bg.length !== 3 || a.bg.some((x) => !(x >= 0 && x <= 1))) throw new Error("--bg wants r,g,b in 0..1");
    } else if (k === "--three") a.three = true;
    else if (k === "--babylon") a.babylon = true;
    else if (k === "--babylon-pose") a.babylonPose = true;
    else if (k === "--babylon-no-render") a.babylonRender = false;
    else if (k === "--clip") a.clip = v();
    else if (k === "--frame") a.frame = Number(v());
    else if (k === "--timeout-ms") a.timeoutMs = Number(v());
    else throw new Error(`unknown argument ${k}`);
  }
  if (!a.glb || !a.out || !a.camera) throw new Error("need --glb, --out and --camera");
  if (!a.three && !a.babylon) a.three = a.babylon = true;
  if (a.clip !== undefined && !(Number.isInteger(a.frame) && a.frame >= 0)) throw new Error("--clip needs --frame F (an integer >= 0)");
  if (a.babylonPose && a.clip === undefined) throw new Error("--babylon-pose needs --clip and --frame");
  return a;
}

// The kinesplat camera as OpenGL matrices (column-major, as three.js's fromArray and Babylon's
// Matrix.FromArray read them), the same mapping as the viewer's applyKinesplatCamera: the
// projection puts pixel (u, v) of the OpenCV camera at the same place of the canvas (y down,
// principal point anywhere), the camera-to-world matrix is [R^T | -R^T t] with the y and z axes
// flipped (OpenCV -> OpenGL camera).
function glCamera(c, near, far) {
  const { width: W, height: H, fx, fy, cx, cy, R, t } = c;
  const projection = [
    (2 * fx) / W, 0, 0, 0,
    0, (2 * fy) / H, 0, 0,
    1 - (2 * cx) / W, (2 * cy) / H - 1, -(far + near) / (far - near), -1,
    0, 0, (-2 * far * near) / (far - near), 0,
  ];
  const C = [0, 1, 2].map((k) => -(R[0][k] * t[0] + R[1][k] * t[1] + R[2][k] * t[2]));
  const cameraToWorld = [
    R[0][0], R[0][1], R[0][2], 0,
    -R[1][0], -R[1][1], -R[1][2], 0,
    -R[2][0], -R[2][1], -R[2][2], 0,
    C[0], C[1], C[2], 1,
  ];
  const forward = R[2];
  return {
    projection,
    cameraToWorld,
    eye: C,
    target: [C[0] + forward[0], C[1] + forward[1], C[2] + forward[2]],
    up: [-R[1][0], -R[1][1], -R[1][2]],
    near,
    far,
  };
}

const types = { ".html": "text/html", ".js": "text/javascript", ".mjs": "text/javascript", ".json": "application/json", ".glb": "model/gltf-binary", ".wasm": "application/wasm" };

// Serves this folder (the pages, node_modules) and the GLB as /model.glb, on 127.0.0.1 only.
function serve(glb) {
  const server = createServer((req, res) => {
    const url = new URL(req.url, "http://127.0.0.1");
    let file;
    if (url.pathname === "/model.glb") file = glb;
    else {
      file = normalize(join(here, decodeURIComponent(url.pathname)));
      if (!file.startsWith(here + sep)) file = null;
    }
    let size = -1;
    try {
      if (file) size = statSync(file).isFile() ? statSync(file).size : -1;
    } catch {
      size = -1;
    }
    if (size < 0) {
      res.writeHead(404, { "content-type": "text/plain" });
      res.end("not found\n");
      return;
    }
    res.writeHead(200, { "content-type": types[extname(file)] || "application/octet-stream", "content-length": size, "cache-control": "no-store" });
    createReadStream(file).pipe(res);
  });
  return new Promise((ok, fail) => {
    server.on("error", fail);
    server.listen(0, "127.0.0.1", () => ok(server));
  });
}

function withTimeout(promise, ms, what) {
  let timer;
  return Promise.race([
    promise.finally(() => clearTimeout(timer)),
    new Promise((_, fail) => {
      timer = setTimeout(() => fail(new Error(`${what} did not finish in ${ms} ms`)), ms);
    }),
  ]);
}

function writeDataUrl(dataUrl, path) {
  const prefix = "data:image/png;base64,";
  if (typeof dataUrl !== "string" || !dataUrl.startsWith(prefix)) throw new Error(`no PNG for ${path}`);
  writeFileSync(path, Buffer.from(dataUrl.slice(prefix.length), "base64"));
  return path;
}

let args;
const result = { ok: false };
let browser = null;
let server = null;
try {
  args = parseArgs(process.argv);
  mkdirSync(args.out, { recursive: true });
  const glb = resolve(args.glb);
  result.glb = glb;
  result.glb_bytes = statSync(glb).size;
  const loadCamera = (path) => {
    const c = JSON.parse(readFileSync(path, "utf8"));
    for (const k of ["width", "height", "fx", "fy", "cx", "cy", "R", "t"])
      if (c[k] === undefined) throw new Error(`${path}: the camera has no "${k}"`);
    return c;
  };
  const cam = loadCamera(args.camera);
  const babylonCam = args.babylonCamera ? loadCamera(args.babylonCamera) : cam;
  server = await serve(glb);
  const base = `http://127.0.0.1:${server.address().port}`;

  const tLaunch = performance.now();
  browser = await chromium.launch(chromiumLaunchOptions());
  result.chromium = browser.version();
  result.timings = { launch_ms: performance.now() - tLaunch };
  const logs = [];
  result.logs = logs;

  async function runPage(html, fn, c, pageArgs) {
    const page = await browser.newPage({ viewport: { width: c.width, height: c.height }, deviceScaleFactor: 1 });
    page.on("console", (m) => logs.push(`[${html} ${m.type()}] ${m.text()}`));
    page.on("pageerror", (e) => logs.push(`[${html} pageerror] ${e.message}`));
    page.on("requestfailed", (r) => logs.push(`[${html} requestfailed] ${r.url()}`));
    const t0 = performance.now();
    await page.goto(`${base}/${html}`, { waitUntil: "load", timeout: args.timeoutMs });
    await page.waitForFunction(() => window.ksPageReady === true, null, { timeout: args.timeoutMs, polling: 50 });
    const pageLoad = performance.now() - t0;
    const all = { glb: "/model.glb", width: c.width, height: c.height, background: args.bg, ...glCamera(c, 0.01, 100), ...pageArgs };
    const r = await withTimeout(page.evaluate(([f, a]) => window[f](a), [fn, all]), args.timeoutMs, html);
    r.timings.page_ms = pageLoad;
    r.timings.wall_ms = performance.now() - t0;
    await page.close();
    return r;
  }

  if (args.three) {
    const r = await runPage("three.html", "ksRenderThree", cam, { clip: args.clip ?? null, frame: args.frame ?? 0 });
    r.png = writeDataUrl(r.png, join(args.out, "three.png"));
    result.three = r;
    result.renderer = r.renderer;
  }
  if (args.babylon) {
    const fps = (() => {
      if (!args.babylonPose) return null;
      // The animation's extras.fps, read from the GLB's JSON chunk.
      const b = readFileSync(glb);
      const len = b.readUInt32LE(12);
      const j = JSON.parse(b.subarray(20, 20 + len).toString("utf8"));
      const a = (j.animations || []).find((x) => x.name === args.clip);
      if (!a || !a.extras || !(a.extras.fps > 0)) throw new Error(`the GLB has no animation ${args.clip} with extras.fps`);
      return a.extras.fps;
    })();
    const r = await runPage("babylon.html", "ksRenderBabylon", babylonCam, {
      render: args.babylonRender,
      clip: args.babylonPose ? args.clip : null,
      frame: args.frame ?? 0,
      fps,
      timeoutMs: args.timeoutMs,
    });
    if (r.png) r.png = writeDataUrl(r.png, join(args.out, "babylon.png"));
    if (r.posed_png) r.posed_png = writeDataUrl(r.posed_png, join(args.out, "babylon_posed.png"));
    if (r.posed_mesh_png) r.posed_mesh_png = writeDataUrl(r.posed_mesh_png, join(args.out, "babylon_posed_mesh.png"));
    result.babylon = r;
    result.renderer = result.renderer || r.renderer;
  }
  result.ok = true;
} catch (e) {
  result.error = String(e && e.message ? e.message : e);
}
if (browser) await browser.close().catch(() => {});
if (server) server.close();
result.timings = { ...(result.timings || {}), total_ms: performance.now() - tStart };
const line = JSON.stringify(result);
if (args && args.out) {
  try {
    writeFileSync(join(args.out, "result.json"), line + "\n");
  } catch {
    // the folder could not be made: the message below says why
  }
}
console.log(line);
if (!result.ok) {
  console.error(`render.mjs: ${result.error}`);
  if (result.logs && result.logs.length) console.error(result.logs.join("\n"));
  process.exit(1);
}
