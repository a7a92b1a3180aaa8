// three.js's own GLTFLoader (the viewer's pinned three, viewer/node_modules) reads a GLB in Node
// and poses its skinned mesh with AnimationMixer at given frames of one clip.
// Usage: node three_pose.mjs VIEWER_DIR FILE.glb CLIP FPS FRAME...
// Prints JSON: {"clips": [[name, duration, tracks]], "skinned": [name, bones, vertices],
// "points": [name, count], "textures": N, "frames": {"F": [x0, y0, z0, x1, ...]}} (skinned
// vertex positions). Node has no image decoder: the textures load as empty three.js textures
// (counted in "textures"); tests/gltf/browser/ checks the texture itself in Chromium.
import { readFile } from "node:fs/promises";
import path from "node:path";
import { pathToFileURL } from "node:url";

const [viewer, file, clipName, fpsText, ...frames] = process.argv.slice(2);
const three = path.join(viewer, "node_modules", "three");
const THREE = await import(pathToFileURL(path.join(three, "build", "three.module.js")).href);
const { GLTFLoader } = await import(
  pathToFileURL(path.join(three, "examples", "jsm", "loaders", "GLTFLoader.js")).href);

const buf = await readFile(file);
let textures = 0;
const loader = new GLTFLoader().register(() => ({
  name: "kinesplat_node_textures",
  loadTexture: () => {
    ++textures;
    return Promise.resolve(new THREE.Texture());
  },
}));
const gltf = await loader.parseAsync(
  buf.buffer.slice(buf.byteOffset, buf.byteOffset + buf.byteLength), "");
const out = { clips: gltf.animations.map((c) => [c.name, c.duration, c.tracks.length]), frames: {} };
out.textures = textures;
let mesh = null;
gltf.scene.traverse((o) => {
  if (o.isSkinnedMesh && !mesh) mesh = o;
  if (o.isPoints) out.points = [o.name, o.geometry.attributes.position.count];
});
if (mesh) {
  out.skinned = [mesh.name, mesh.skeleton.bones.length, mesh.geometry.attributes.position.count];
  const clip = gltf.animations.find((c) => c.name === clipName);
  const mixer = new THREE.AnimationMixer(gltf.scene);
  if (clip) mixer.clipAction(clip).play();
  const v = new THREE.Vector3();
  for (const f of frames) {
    mixer.setTime(Number(f) / Number(fpsText));
    gltf.scene.updateMatrixWorld(true);
    mesh.skeleton.update();
    const n = mesh.geometry.attributes.position.count;
    const p = new Array(3 * n);
    for (let i = 0; i < n; ++i) {
      mesh.getVertexPosition(i, v);
      mesh.localToWorld(v);
      p[3 * i] = v.x;
      p[3 * i + 1] = v.y;
      p[3 * i + 2] = v.z;
    }
    out.frames[f] = p;
  }
}
console.log(JSON.stringify(out));
