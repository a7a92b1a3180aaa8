// How kinesplat's browser checks start Debian's Chromium headless (viewer/test/capture.mjs,
// studio/test/drive.mjs, tests/gltf/browser/render.mjs): software WebGL through SwiftShader, no
// background traffic. KS_CHROMIUM overrides the browser. playwright-core starts it with a fresh
// temporary profile (--user-data-dir).
export function chromiumLaunchOptions() {
  return {
    executablePath: process.env.KS_CHROMIUM || "/usr/bin/chromium",
    headless: true,
    args: [
      "--no-sandbox",
      "--disable-gpu",
      "--enable-unsafe-swiftshader",
      "--use-angle=swiftshader",
      "--disable-background-networking",
      "--disable-component-update",
      "--disable-sync",
      "--no-first-run",
    ],
  };
}
