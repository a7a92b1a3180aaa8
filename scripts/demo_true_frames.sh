#!/usr/bin/env bash
# kinesplat true-frames demo (`make demo-true-frames`; `make demo` runs scripts/demo.sh, from the
# photo alone): the open default body posed and written as OBJ; a synthetic clothed person with exact ground truth; an avatar reconstructed from its 64-frame pose-space turn;
# evaluation on 32 held-out frames (8 novel poses x 4 views, at full resolution); a turntable video,
# a motion video and a rest-pose 3DGS .ply.
# Usage: scripts/demo_true_frames.sh [path/to/kinesplat] [output dir]
# Tunables (environment): KS_DEMO_ITERS (reconstruct steps, 1600), KS_DEMO_SUBDIVIDE (template Loop
# levels, 2), KS_DEMO_SCALE (training resolution, 1 = the images'), KS_DEMO_SIZE (video size WxH,
# 384x512), KS_DEMO_MOTION (second video, dance). A quick look (about a minute of training):
# KS_DEMO_SUBDIVIDE=1 KS_DEMO_SCALE=0.5. Paper-sized setting (an hour or more on 2 cores):
# KS_DEMO_ITERS=2000.
set -euo pipefail

KS=${1:-build/kinesplat}
OUT=${2:-demo-out}
ITERS=${KS_DEMO_ITERS:-1600}
SUBDIV=${KS_DEMO_SUBDIVIDE:-2}
TRAIN_SCALE=${KS_DEMO_SCALE:-1}
SIZE=${KS_DEMO_SIZE:-384x512}
MOTION=${KS_DEMO_MOTION:-dance}

if [ ! -x "$KS" ]; then
  echo "demo: $KS not found or not executable (run 'make build' first)" >&2
  exit 1
fi
mkdir -p "$OUT"
T0=$(date +%s)
step() { echo; echo "== demo [$(( $(date +%s) - T0 ))s] $*"; }

BODY="$OUT/body"
SUBJECT="$OUT/subject"
AVATAR="$OUT/avatar.ksavatar"

# 0. The open default body model, posed (OBJ, vertices in model order).
step "body: default model -> $BODY (rest, walk, wave)"
mkdir -p "$BODY"
"$KS" body make-default --out "$BODY/default_body.npz"
"$KS" body info default > "$BODY/default_body_info.json"
"$KS" body pose default --out "$BODY/rest.obj" --joints "$BODY/rest_joints.json"
# body_pose: 3 values per joint 1..23 (left_hip, right_hip, spine1, left_knee, ...).
cat > "$BODY/pose_walk.json" <<'JSON'
{"betas": [0.5, 0.3], "global_orient": [0.0, 0.3, 0.0],
 "body_pose": [-0.5,0,0, 0.4,0,0, 0,0,0,  0.6,0,0, 0.3,0,0, 0,0,0,  0,0,0, 0,0,0, 0,0,0,
               0,0,0, 0,0,0, 0,0,0,  0,0,0, 0,0,0, 0,0,0,  0,0,-1.1, 0,0,1.1, 0,-0.6,0,
               0,0.6,0, 0,0,0, 0,0,0,  0,0,0, 0,0,0]}
JSON
"$KS" body pose default --params "$BODY/pose_walk.json" --out "$BODY/walk.obj"
cat > "$BODY/pose_wave.json" <<'JSON'
{"betas": [-0.5, 1.0, 0, 0, 0, 0, 0.5],
 "body_pose": [0,0,0.2, 0,0,-0.2, 0,0,0,  0,0,0, 0,0,0, 0,0,0,  0,0,0, 0,0,0, 0,0,0,
               0,0,0, 0,0,0, 0,0,0,  0,0,0, 0,0,0, 0,0.5,0,  0,0,0.9, 0,0,0, 0,-1.2,0,
               0,0,0, 0,0,0, 0,0,0,  0,0,0, 0,0,0]}
JSON
"$KS" body pose default --params "$BODY/pose_wave.json" --out "$BODY/wave_subdiv1.obj" --subdivide 1

# 1. A synthetic clothed person with exact ground truth (train/ and test/ datasets).
step "synth --seed 0 -> $SUBJECT"
"$KS" synth --seed 0 --out "$SUBJECT"

# 2. Reconstruct the avatar from the training views (the stand-in for a generator's output).
step "reconstruct $SUBJECT/train -> $AVATAR ($ITERS steps, $SUBDIV Loop levels, scale $TRAIN_SCALE, density control gpdc)"
"$KS" reconstruct "$SUBJECT/train" --out "$AVATAR" --iters "$ITERS" --subdivide "$SUBDIV" \
  --scale "$TRAIN_SCALE" --density gpdc

# 3. Evaluate on the held-out views (novel poses and views), full resolution.
step "evaluate $AVATAR on $SUBJECT/test"
"$KS" evaluate "$AVATAR" "$SUBJECT/test" --out "$OUT/metrics.json" --renders "$OUT/eval"

# 4. Videos: a turntable (the avatar turns 360 degrees in place, fixed camera) and a motion.
step "animate turntable -> $OUT/turntable.mp4"
"$KS" animate "$AVATAR" --motion turn --camera front --size "$SIZE" --out "$OUT/turntable.mp4"
step "animate $MOTION -> $OUT/$MOTION.mp4"
"$KS" animate "$AVATAR" --motion "$MOTION" --camera front --size "$SIZE" --out "$OUT/$MOTION.mp4"

step "export rest-pose .ply -> $OUT/avatar.ply"
"$KS" export "$AVATAR" --out "$OUT/avatar.ply"

echo
echo "== demo done in $(( $(date +%s) - T0 ))s. Results in $OUT/:"
for f in "$BODY" "$SUBJECT" "$AVATAR" "$OUT/metrics.json" "$OUT/eval" "$OUT/turntable.mp4" \
         "$OUT/$MOTION.mp4" "$OUT/avatar.ply"; do
  echo "  $f"
done
