// Babylon.js's glTF loader (babylonjs-loaders, with its KHR_gaussian_splatting extension, which
// the UMD bundle registers) reads kinesplat's GLB. render.mjs calls window.ksRenderBabylon(args)
// and gets back what the loader made (meshes and their classes, the GaussianSplattingMesh and its
// splat count, skeletons, animation groups), the timings and, unless args.render is false, the
// splats alone (the skinned mesh disabled) at rest through a kinesplat camera as a PNG data URL;
// with args.clip, also the same after the animation group `clip` went to frame args.frame (to see
// whether Babylon skins the splat primitive).
//   args: {glb, width, height, projection (16, column-major, OpenGL), eye, target, up,
//          background [r, g, b], render, clip, frame, timeoutMs}
/* global BABYLON */

function webglRenderer(gl) {
  const dbg = gl.getExtension("WEBGL_debug_renderer_info");
  return dbg ? gl.getParameter(dbg.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
}

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

// Renders until the splats' depth sort has settled for this camera (Babylon sorts in a worker and
// shows nothing before the first sort comes back), then a few frames more. Returns the frames drawn.
async function renderSettled(scene, splats, timeoutMs) {
  const end = performance.now() + timeoutMs;
  let frames = 0;
  let settledFor = 0;
  while (performance.now() < end) {
    scene.render();
    ++frames;
    const settled = splats.length === 0 || splats.every((m) => m._isDepthSortSettled === true);
    settledFor = settled ? settledFor + 1 : 0;
    if (settledFor >= 3) return frames;
    await sleep(20);
  }
  throw new Error(`the splats' depth sort did not settle in ${timeoutMs} ms (${frames} frames drawn)`);
}

function readPixels(gl, w, h) {
  const px = new Uint8Array(4 * w * h);
  gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
  return px;
}

window.ksRenderBabylon = async (args) => {
  const out = { engine: "Babylon.js", version: BABYLON.Engine.Version, timings: {} };
  const t0 = performance.now();
  const canvas = document.createElement("canvas");
  canvas.width = args.width;
  canvas.height = args.height;
  canvas.style.width = `${args.width}px`;
  canvas.style.height = `${args.height}px`;
  document.body.appendChild(canvas);
  const engine = new BABYLON.Engine(canvas, false, { preserveDrawingBuffer: true, stencil: true, alpha: false }, false);
  engine.setHardwareScalingLevel(1);
  const gl = engine._gl;
  out.renderer = webglRenderer(gl);
  out.webgl_version = engine.webGLVersion;

  const scene = new BABYLON.Scene(engine);
  scene.useRightHandedSystem = true;
  scene.clearColor = new BABYLON.Color4(args.background[0], args.background[1], args.background[2], 1);
  scene.autoClear = true;

  const t1 = performance.now();
  const result = await BABYLON.ImportMeshAsync(args.glb, scene, {
    pluginOptions: { gltf: { animationStartMode: BABYLON.GLTFLoaderAnimationStartMode.NONE } },
  });
  out.timings.load_ms = performance.now() - t1;

  const splats = [];
  out.meshes = result.meshes.map((m) => {
    const cls = m.getClassName();
    const e = { name: m.name, class: cls, vertices: m.getTotalVertices() };
    if (m.parent) e.parent = m.parent.name;
    if (m.skeleton) e.skeleton = { name: m.skeleton.name, bones: m.skeleton.bones.length };
    if (m.isVerticesDataPresent) e.matrices_indices = m.isVerticesDataPresent(BABYLON.VertexBuffer.MatricesIndicesKind);
    e.num_bone_influencers = m.numBoneInfluencers;
    if (m instanceof BABYLON.GaussianSplattingMesh || cls === "GaussianSplattingMesh") {
      e.splat_count = m.renderedSplatCount; // the source splats
      e.splat_index_length = m.splatCount; // Babylon's sort index, padded to a multiple of 16
      e.sh_degree = m.shDegree;
      e.kernel_size = m.kernelSize;
      e.compensation = m.compensation;
      splats.push(m);
    }
    return e;
  });
  const root = result.meshes.find((m) => m.name === "__root__");
  if (root) {
    root.computeWorldMatrix(true);
    out.root = {
      scaling: root.scaling.asArray(),
      rotation: root.rotationQuaternion ? root.rotationQuaternion.asArray() : root.rotation.asArray(),
      world: Array.from(root.getWorldMatrix().m),
    };
  }
  out.skeletons = result.skeletons.map((s) => ({ name: s.name, bones: s.bones.length }));
  out.animation_groups = result.animationGroups.map((g) => {
    const a = g.targetedAnimations.length ? g.targetedAnimations[0].animation : null;
    return {
      name: g.name,
      from: g.from,
      to: g.to,
      targeted: g.targetedAnimations.length,
      frames_per_second: a ? a.framePerSecond : null,
    };
  });
  out.splat_count = splats.reduce((s, m) => s + (m.renderedSplatCount || 0), 0);
  out.skinned_mesh = result.meshes.some((m) => m.name === "avatar_mesh" && m.skeleton && m.getTotalVertices() > 0);

  if (args.render !== false) {
    if (splats.length === 0) throw new Error("Babylon made no GaussianSplattingMesh from the GLB");
    for (const m of result.meshes)
      if (m.getTotalVertices() > 0 && !splats.includes(m)) m.setEnabled(false);
    const camera = new BABYLON.FreeCamera("kinesplat", BABYLON.Vector3.FromArray(args.eye), scene);
    camera.upVector = BABYLON.Vector3.FromArray(args.up);
    camera.setTarget(BABYLON.Vector3.FromArray(args.target));
    camera.minZ = args.near;
    camera.maxZ = args.far;
    camera.freezeProjectionMatrix(BABYLON.Matrix.FromArray(args.projection));
    scene.activeCamera = camera;

    await scene.whenReadyAsync();
    const t2 = performance.now();
    out.frames_to_settle = await renderSettled(scene, splats, args.timeoutMs);
    out.timings.rest_render_ms = performance.now() - t2;
    const rest = readPixels(gl, args.width, args.height);
    out.png = canvas.toDataURL("image/png");
    out.corner_rgba = Array.from(rest.slice(0, 4));
    const t3 = performance.now();
    scene.render();
    readPixels(gl, 1, 1);
    out.timings.render_ms = performance.now() - t3;

    if (args.clip) {
      const g = result.animationGroups.find((x) => x.name === args.clip);
      if (!g) throw new Error(`no animation group named ${args.clip}`);
      const fpsGltf = args.fps;
      const fpsBabylon = g.targetedAnimations[0].animation.framePerSecond;
      const f = (args.frame / fpsGltf) * fpsBabylon;
      g.start(false, 1, g.from, g.to);
      g.pause();
      g.goToFrame(f);
      out.posed = { clip: args.clip, frame: args.frame, babylon_frame: f };
      const bones = splats.map((m) => (m.skeleton ? m.skeleton : null)).filter((s) => s);
      out.posed.splat_skeletons = bones.length;
      const t4 = performance.now();
      // The camera did not move: the sort settles at once unless the splats moved.
      for (const m of splats) if (m._postToWorker) m._postToWorker(true);
      out.posed.frames = await renderSettled(scene, splats, args.timeoutMs);
      out.timings.posed_render_ms = performance.now() - t4;
      const posed = readPixels(gl, args.width, args.height);
      let changed = 0;
      for (let i = 0; i < posed.length; i += 4) {
        const d = Math.max(Math.abs(posed[i] - rest[i]), Math.abs(posed[i + 1] - rest[i + 1]), Math.abs(posed[i + 2] - rest[i + 2]));
        if (d > 8) ++changed;
      }
      out.posed.changed_share = changed / (args.width * args.height);
      out.posed_png = canvas.toDataURL("image/png");
      // The skinned mesh posed by the same group, drawn alone: the group does move the skeleton.
      const mesh = result.meshes.find((m) => m.name === "avatar_mesh");
      if (mesh) {
        for (const m of splats) m.setEnabled(false);
        mesh.setEnabled(true);
        await scene.whenReadyAsync();
        await renderSettled(scene, [], args.timeoutMs);
        out.posed_mesh_png = canvas.toDataURL("image/png");
      }
    }
  }
  out.timings.total_ms = performance.now() - t0;
  engine.dispose();
  return out;
};
window.ksPageReady = true;
