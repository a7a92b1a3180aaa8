// Validates one .glb with Khronos glTF-Validator and prints its report as JSON on stdout.
// Usage: node validate.mjs FILE.glb   (exit 0 when the report has no errors, 1 otherwise)
import { readFile } from "node:fs/promises";
import validator from "gltf-validator";

const file = process.argv[2];
if (!file) {
  console.error("usage: node validate.mjs FILE.glb");
  process.exit(2);
}
const data = new Uint8Array(await readFile(file));
const report = await validator.validateBytes(data, {
  uri: file,
  maxIssues: 200,
  externalResourceFunction: () => Promise.reject(new Error("no external resources")),
});
console.log(JSON.stringify(report, null, 1));
process.exit(report.issues.numErrors === 0 ? 0 : 1);
