#!/usr/bin/env bash
# kinesplat demo (what `make demo` runs): one photo -> an animatable avatar. A synthetic clothed
# person with exact ground truth is made; only its photo (photo.png) goes into `kinesplat create`
# (perceive -> fit -> sample -> generate (lift) -> augment -> reconstruct -> videos); the avatar is
# then evaluated on the person's held-out test split (8 novel poses x 4 views the photo never saw,
# aligned through the fit; front / side / back reported apart), and the figures printed.
# The true-frames path (an avatar from the synth's 64 true training views) is
# scripts/demo_true_frames.sh (`make demo-true-frames`).
# Usage: scripts/demo.sh [path/to/kinesplat] [output dir]
# Environment: KS_DEMO_SEED (synth person, 0), KS_DEMO_ITERS (reconstruct steps, create's default),
# KS_DEMO_PHOTO (your own photo instead of the synth's: no evaluation then).
set -euo pipefail

KS=${1:-build/kinesplat}
OUT=${2:-demo-out}
SEED=${KS_DEMO_SEED:-0}

if [ ! -x "$KS" ]; then
  echo "demo: $KS not found or not executable (run 'make build' first)" >&2
  exit 1
fi
mkdir -p "$OUT"
T0=$(date +%s)
step() { echo; echo "== demo [$(( $(date +%s) - T0 ))s] $*"; }

ITERS=()
[ -n "${KS_DEMO_ITERS:-}" ] && ITERS=(--iters "$KS_DEMO_ITERS")

if [ -n "${KS_DEMO_PHOTO:-}" ]; then
  step "create $KS_DEMO_PHOTO -> $OUT/create"
  "$KS" create "$KS_DEMO_PHOTO" --out "$OUT/create" "${ITERS[@]}"
  exit 0
fi

SYNTH="$OUT/synth"
step "synth --seed $SEED -> $SYNTH (photo.png, and the truth: subject.json, test/)"
if [ -f "$SYNTH/test/dataset.json" ] && [ -f "$SYNTH/photo.png" ]; then
  echo "demo: $SYNTH exists, kept"
else
  "$KS" synth --seed "$SEED" --out "$SYNTH"
fi

step "create $SYNTH/photo.png -> $OUT/create (the photo alone)"
"$KS" create "$SYNTH/photo.png" --out "$OUT/create" "${ITERS[@]}"

step "evaluate the avatar on $SYNTH/test (novel poses and views; aligned through the fit)"
"$KS" evaluate "$OUT/create/avatar.ksavatar" "$SYNTH/test" \
  --fit "$OUT/create/subject/fit.json" --truth "$SYNTH/subject.json" \
  --out "$OUT/metrics.json" --renders "$OUT/eval" -q | tail -7

step "fit against the truth"
"$KS" evaluate-fit "$OUT/create/subject/fit.json" "$SYNTH/subject.json" --out "$OUT/fit_metrics.json"

echo
echo "== demo done in $(( $(date +%s) - T0 ))s. Results in $OUT/:"
for f in "$SYNTH/photo.png" "$OUT/create/subject/fit_overlay.png" "$OUT/create/prior/refined" \
         "$OUT/create/avatar.ksavatar" "$OUT/create/turntable.mp4" "$OUT/create/dance.mp4" \
         "$OUT/metrics.json" "$OUT/fit_metrics.json" "$OUT/eval"; do
  echo "  $f"
done
