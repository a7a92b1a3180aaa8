// three.js's GLTFLoader reads kinesplat's GLB; the skinned mesh `avatar_mesh` alone (the splat
// points hidden), posed by AnimationMixer at one frame of a named clip, unlit in its own colour
// (COLOR_0 and / or the base-colour texture), seen through a kinesplat camera. render.mjs calls
// window.ksRenderThree(args) and gets back what was loaded, the timings and the PNG as a data URL.
//   args: {glb, width, height, projection (16, column-major), cameraToWorld (16, column-major),
//          background [r, g, b] (display sRGB), clip (name or null), frame}
import * as THREE from "three";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";

function webglRenderer(gl) {
  const dbg = gl.getExtension("WEBGL_debug_renderer_info");
  return dbg ? gl.getParameter(dbg.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
}

window.ksRenderThree = async (args) => {
  const out = { engine: "three.js", version: THREE.REVISION, timings: {} };
  const t0 = performance.now();
  const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true, alpha: false });
  renderer.setPixelRatio(1);
  renderer.setSize(args.width, args.height);
  renderer.outputColorSpace = THREE.SRGBColorSpace;
  const bg = new THREE.Color().setRGB(args.background[0], args.background[1], args.background[2], THREE.SRGBColorSpace);
  renderer.setClearColor(bg, 1);
  document.body.appendChild(renderer.domElement);
  out.renderer = webglRenderer(renderer.getContext());

  const t1 = performance.now();
  const gltf = await new GLTFLoader().loadAsync(args.glb);
  out.timings.load_ms = performance.now() - t1;

  let mesh = null;
  const points = [];
  const others = [];
  gltf.scene.traverse((o) => {
    if (o.isSkinnedMesh && o.name === "avatar_mesh" && !mesh) mesh = o;
    else if (o.isPoints) points.push(o);
    else if (o.isMesh) others.push(o);
  });
  if (!mesh) throw new Error("no SkinnedMesh named avatar_mesh in the GLB");
  for (const o of [...points, ...others]) o.visible = false;
  out.points = points.map((p) => [p.name, p.geometry.attributes.position.count]);
  out.hidden_meshes = others.map((o) => o.name);

  const geom = mesh.geometry;
  const loaded = mesh.material;
  const hasColors = !!geom.attributes.color;
  // glTF's base colour is factor x texture x COLOR_0: MeshBasicMaterial multiplies the same three,
  // unlit. COLOR_0 and the factor are linear, the texture is sRGB (GLTFLoader tags it so); the
  // renderer writes sRGB.
  mesh.material = new THREE.MeshBasicMaterial({
    color: loaded.color ? loaded.color.clone() : new THREE.Color(1, 1, 1),
    map: loaded.map || null,
    vertexColors: hasColors,
    side: THREE.FrontSide,
  });
  mesh.frustumCulled = false;
  out.mesh = {
    name: mesh.name,
    vertices: geom.attributes.position.count,
    triangles: geom.index ? geom.index.count / 3 : geom.attributes.position.count / 3,
    bones: mesh.skeleton.bones.length,
    color_0: hasColors ? geom.attributes.color.itemSize : 0,
    base_color_texture: loaded.map ? [loaded.map.image.width, loaded.map.image.height] : null,
    base_color_factor: loaded.color ? loaded.color.toArray() : null,
  };

  const json = gltf.parser.json;
  out.clips = gltf.animations.map((c, i) => ({
    name: c.name,
    duration: c.duration,
    tracks: c.tracks.length,
    extras: (json.animations && json.animations[i] && json.animations[i].extras) || null,
  }));
  const mixer = new THREE.AnimationMixer(gltf.scene);
  if (args.clip) {
    const i = gltf.animations.findIndex((c) => c.name === args.clip);
    if (i < 0) throw new Error(`no animation named ${args.clip} (have: ${gltf.animations.map((c) => c.name).join(", ")})`);
    const fps = out.clips[i].extras && out.clips[i].extras.fps;
    if (!(fps > 0)) throw new Error(`animation ${args.clip} has no extras.fps`);
    mixer.clipAction(gltf.animations[i]).play();
    out.time = args.frame / fps;
    mixer.setTime(out.time);
    out.fps = fps;
  }

  const scene = new THREE.Scene();
  scene.add(gltf.scene);
  const camera = new THREE.PerspectiveCamera();
  camera.projectionMatrix.fromArray(args.projection);
  camera.projectionMatrixInverse.copy(camera.projectionMatrix).invert();
  camera.matrixAutoUpdate = false;
  camera.matrix.fromArray(args.cameraToWorld);
  camera.matrix.decompose(camera.position, camera.quaternion, camera.scale);
  camera.updateMatrixWorld(true);
  scene.updateMatrixWorld(true);

  const t2 = performance.now();
  renderer.render(scene, camera);
  const gl = renderer.getContext();
  const px = new Uint8Array(4);
  gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px); // waits for the drawing
  out.timings.first_render_ms = performance.now() - t2;
  const t3 = performance.now();
  renderer.render(scene, camera);
  gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
  out.timings.render_ms = performance.now() - t3;
  out.corner_rgba = Array.from(px);
  out.png = renderer.domElement.toDataURL("image/png");
  out.timings.total_ms = performance.now() - t0;
  return out;
};
window.ksPageReady = true;
