#!/usr/bin/env bash
# The main job on the built-in example. For now (until the later stages land): generate the open
# default body model and pose it in a few poses, writing OBJs into the demo output folder.
set -euo pipefail
bin=${1:-build/kinesplat}
out=${2:-demo-out}
mkdir -p "$out"
"$bin" info
"$bin" body make-default --out "$out/default_body.npz"
"$bin" body info default > "$out/default_body_info.json"
"$bin" body pose default --out "$out/body_rest.obj" --joints "$out/body_rest_joints.json"
# Walking-like pose: left hip forward, right hip back, knees bent, arms down, elbows bent.
cat > "$out/pose_walk.json" <<'JSON'
{
  "betas": [0.5, 0.3],
  "global_orient": [0.0, 0.3, 0.0],
  "body_pose": [-0.5, 0, 0,   0.4, 0, 0,   0, 0, 0,
                 0.6, 0, 0,   0.3, 0, 0,   0, 0, 0,
                 0, 0, 0,     0, 0, 0,     0, 0, 0,
                 0, 0, 0,     0, 0, 0,     0, 0, 0,
                 0, 0, 0,     0, 0, 0,     0, 0, 0,
                 0, 0, -1.1,  0, 0, 1.1,   0, -0.6, 0,
                 0, 0.6, 0,   0, 0, 0,     0, 0, 0,
                 0, 0, 0,     0, 0, 0],
  "transl": [0.0, 0.0, 0.0]
}
JSON
"$bin" body pose default --params "$out/pose_walk.json" --out "$out/body_walk.obj"
# Arms raised, head turned, with one level of Loop subdivision.
cat > "$out/pose_wave.json" <<'JSON'
{
  "betas": [-0.5, 1.0, 0, 0, 0, 0, 0.5],
  "body_pose": [0, 0, 0.2,  0, 0, -0.2,  0, 0, 0,
                0, 0, 0,    0, 0, 0,     0, 0, 0,
                0, 0, 0,    0, 0, 0,     0, 0, 0,
                0, 0, 0,    0, 0, 0,     0, 0, 0,
                0, 0, 0,    0, 0, 0,     0, 0.5, 0,
                0, 0, 0.9,  0, 0, 0,     0, -1.2, 0,
                0, 0, 0,    0, 0, 0,     0, 0, 0,
                0, 0, 0,    0, 0, 0],
  "transl": [0.0, 0.0, 0.0]
}
JSON
"$bin" body pose default --params "$out/pose_wave.json" --out "$out/body_wave_subdiv.obj" --subdivide 1
echo "demo: wrote $(ls "$out"/*.obj | wc -l) OBJ files to $out"
