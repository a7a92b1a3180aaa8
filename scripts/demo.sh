#!/usr/bin/env bash
# kinesplat demo: a synthetic person -> reconstruct an avatar from its training views -> evaluate
# on held-out views -> a turntable video and a motion video (+ a rest-pose .ply).
# Usage: scripts/demo.sh [path/to/kinesplat] [output dir]      (make demo calls it this way)
# Stages whose command is not in this build are skipped with a message. Tunables (environment):
#   KS_DEMO_ITERS (reconstruct steps, 400), KS_DEMO_SUBDIVIDE (template Loop levels, 1),
#   KS_DEMO_SCALE (training resolution, 0.25), KS_DEMO_SIZE (video size WxH, 384x512),
#   KS_DEMO_MOTION (second video, dance). The defaults keep the demo near 10 minutes on 2 cores;
#   the full-quality setting is KS_DEMO_ITERS=2000 KS_DEMO_SUBDIVIDE=2 KS_DEMO_SCALE=0.5.
set -euo pipefail

KS=${1:-build/kinesplat}
OUT=${2:-demo-out}
ITERS=${KS_DEMO_ITERS:-400}
SUBDIV=${KS_DEMO_SUBDIVIDE:-1}
TRAIN_SCALE=${KS_DEMO_SCALE:-0.25}
SIZE=${KS_DEMO_SIZE:-384x512}
MOTION=${KS_DEMO_MOTION:-dance}

if [ ! -x "$KS" ]; then
  echo "demo: $KS not found or not executable (run 'make build' first)" >&2
  exit 1
fi
mkdir -p "$OUT"
HELP=$("$KS" --help 2>&1 || true)
has() { printf '%s\n' "$HELP" | grep -qE "^[[:space:]]+$1([[:space:]]|$)"; }
stamp() { date +%s; }
T0=$(stamp)
step() { echo; echo "== demo [$(( $(stamp) - T0 ))s] $*"; }

AVATAR="$OUT/avatar.ksavatar"
SUBJECT="$OUT/subject"

# 0. The open default body model, posed in a couple of poses (OBJ, vertices in model order).
if has body; then
  BODY="$OUT/body"
  mkdir -p "$BODY"
  step "body: default model -> $BODY (rest, walk, wave)"
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
else
  echo "demo: skipping body (not in this build)"
fi

# 1. A synthetic clothed person with exact ground truth (train/ and test/ datasets).
if has synth; then
  step "synth --seed 0 -> $SUBJECT"
  "$KS" synth --seed 0 --out "$SUBJECT"
else
  echo "demo: skipping synth (not in this build)"
fi

# 2. Reconstruct the avatar from the training views.
if has reconstruct && [ -f "$SUBJECT/train/dataset.json" ]; then
  step "reconstruct $SUBJECT/train -> $AVATAR ($ITERS steps, $SUBDIV Loop levels, scale $TRAIN_SCALE, density control gpdc)"
  "$KS" reconstruct "$SUBJECT/train" --out "$AVATAR" --iters "$ITERS" --subdivide "$SUBDIV" \
    --scale "$TRAIN_SCALE" --density gpdc
else
  echo "demo: skipping reconstruct (command or training dataset missing)"
fi

# 3. Evaluate on the held-out views (novel views and poses).
if has evaluate && [ -f "$AVATAR" ] && [ -f "$SUBJECT/test/dataset.json" ]; then
  step "evaluate $AVATAR on $SUBJECT/test"
  "$KS" evaluate "$AVATAR" "$SUBJECT/test" --out "$OUT/metrics.json" --renders "$OUT/eval" --scale 0.5
else
  echo "demo: skipping evaluate (command, avatar or test dataset missing)"
fi

# 4. Videos: a turntable (the avatar turns 360 degrees in place, fixed camera) and a motion.
if has animate && [ -f "$AVATAR" ]; then
  VIDEO_EXT=mp4
  command -v ffmpeg >/dev/null 2>&1 || { VIDEO_EXT=""; echo "demo: no ffmpeg: writing PNG frames instead of MP4"; }
  name() { if [ -n "$VIDEO_EXT" ]; then echo "$OUT/$1.mp4"; else echo "$OUT/$1"; fi; }
  step "animate turntable -> $(name turntable)"
  "$KS" animate "$AVATAR" --motion turn --camera front --size "$SIZE" --out "$(name turntable)"
  step "animate $MOTION -> $(name "$MOTION")"
  "$KS" animate "$AVATAR" --motion "$MOTION" --camera front --size "$SIZE" --out "$(name "$MOTION")"
else
  echo "demo: skipping videos (animate or the avatar missing)"
fi

if has export && [ -f "$AVATAR" ]; then
  step "export rest-pose .ply -> $OUT/avatar.ply"
  "$KS" export "$AVATAR" --out "$OUT/avatar.ply"
fi

echo
echo "== demo done in $(( $(stamp) - T0 ))s. Results in $OUT/:"
for f in "$OUT/body" "$SUBJECT" "$AVATAR" "$OUT/metrics.json" "$OUT/eval" "$OUT/turntable.mp4" "$OUT/turntable" \
         "$OUT/$MOTION.mp4" "$OUT/$MOTION" "$OUT/avatar.ply"; do
  [ -e "$f" ] && echo "  $f"
done
exit 0
