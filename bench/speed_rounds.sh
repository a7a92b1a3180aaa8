#!/usr/bin/env bash
# Issue 17's render and playback figures, in rounds: each round times the rasterizer bench once
# and plays each avatar once, so that a machine whose speed drifts (a neighbour on the host)
# spreads its slow stretches over every figure alike; then the median, quartiles and range of
# each figure over the rounds, and how many rounds met the issue's bar.
#
#   bench/speed_rounds.sh [AVATAR.ksavatar ...]
#
# A round: `kinesplat bench raster --backward --frames 20` (110,000 Gaussians, 512 x 768:
# forward, forward image only, forward + backward, each the median of 20 frames), then for each
# AVATAR `kinesplat animate AVATAR --out TMP --frames 60` (512 x 768, pose + render per frame,
# the mean of 60 frames, as `animate` reports it). Not part of `make test` or CI.
#
# The machine's state: `bench raster` times a fixed arithmetic load (no memory traffic) before
# and after its figures ("machine speed probe"); a round's probe is the larger of the two. A
# shared host's neighbours slow the probe and every figure alike, so besides the figures over
# all rounds the summary gives them over the rounds whose probe is within 10 % of the fastest
# round's (the machine at its full speed, as on the idle machine the issue's figures assume).
#
# Environment: KINESPLAT (default build/kinesplat), ROUNDS (10), KS_LOCK (a file: each timed
# command holds `flock KS_LOCK`, so that other jobs that take it do not run beside it), TMPDIR.
set -euo pipefail

repo=$(cd "$(dirname "$0")/.." && pwd)
ks=${KINESPLAT:-$repo/build/kinesplat}
[ -x "$ks" ] || { echo "error: $ks not built (make build)" >&2; exit 2; }
rounds=${ROUNDS:-10}
[[ "$rounds" =~ ^[1-9][0-9]*$ ]] || { echo "error: ROUNDS must be a positive integer" >&2; exit 2; }
for a in "$@"; do [ -f "$a" ] || { echo "error: no avatar $a" >&2; exit 2; }; done
work=$(mktemp -d "${TMPDIR:-/tmp}/kinesplat-speed-rounds.XXXXXX")
trap 'rm -rf "$work"' EXIT
run() { if [ -n "${KS_LOCK:-}" ]; then flock "$KS_LOCK" "$@"; else "$@"; fi; }
field() { sed -n "s/^$1: median \([0-9.]*\) ms.*/\1/p" "$2"; }

: >"$work/figures"  # lines: NAME MS ROUND
: >"$work/probes"   # lines: ROUND PROBE_MS
for r in $(seq "$rounds"); do
  run "$ks" bench raster --backward --frames 20 >"$work/bench.txt"
  fwd=$(field forward "$work/bench.txt")
  img=$(sed -n 's/^forward, image only (playback): median \([0-9.]*\) ms.*/\1/p' "$work/bench.txt")
  fb=$(field forward+backward "$work/bench.txt")
  probe=$(sed -n 's/^machine speed probe: \([0-9.]*\) ms before, \([0-9.]*\) ms after.*/\1 \2/p' \
    "$work/bench.txt" | awk '{print ($1 > $2 ? $1 : $2)}')
  [ -n "$probe" ] || { echo "error: bench raster printed no machine speed probe" >&2; exit 1; }
  echo "$r $probe" >>"$work/probes"
  line="round $r: probe $probe ms, forward $fwd ms, image only $img ms, forward + backward $fb ms"
  printf 'forward %s %s\nimage-only %s %s\nforward+backward %s %s\n' "$fwd" "$r" "$img" "$r" \
    "$fb" "$r" >>"$work/figures"
  i=0
  for a in "$@"; do
    i=$((i + 1))
    rm -rf "$work/frames"
    run "$ks" animate "$a" --out "$work/frames" --frames 60 >"$work/animate.txt" 2>&1 ||
      { cat "$work/animate.txt" >&2; exit 1; }
    ms=$(sed -n 's/.*pose + render \([0-9.]*\) ms per frame.*/\1/p' "$work/animate.txt")
    [ -n "$ms" ] || { echo "error: animate $a reported no frame time" >&2; exit 1; }
    echo "playback-$i $ms $r" >>"$work/figures"
    line+=", $(basename "$a") $ms ms"
  done
  echo "$line"
done

# Per figure: median, quartiles, range, and the rounds at or under the bar (ms); over the rounds
# listed in the file $4 (all when it is absent).
summary() {
  local name=$1 bar=$2 label=$3 keep=${4:-}
  awk -v n="$name" -v keep="$keep" 'BEGIN {if (keep != "") while ((getline k < keep) > 0) ok[k] = 1}
    $1 == n && (keep == "" || ($3 in ok)) {print $2}' "$work/figures" | sort -g | awk -v bar="$bar" \
    -v label="$label" '{v[NR] = $1; met += ($1 <= bar)} END {
      med = NR % 2 ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2
      q1 = v[int((NR + 3) / 4)]; q3 = v[int((3 * NR + 3) / 4)]
      printf "%-40s median %7.2f ms (%6.1f FPS)  quartiles %.2f-%.2f  range %.2f-%.2f  %d of %d rounds <= %.2f ms\n",
        label, med, 1000 / med, q1, q3, v[1], v[NR], met, NR, bar}'
}
echo
echo "$rounds rounds ($(nproc) CPUs, $(sed -n 's/.*kernel \([a-z0-9]*\).*/\1/p' "$work/bench.txt") kernel); issue 17's bars: forward 70 FPS, forward + backward 35 ms, playback 60 FPS"
summaries() {
  summary forward 14.2857 "forward (110K, 512x768)" "${1:-}"
  summary image-only 14.2857 "forward, image only (playback's)" "${1:-}"
  summary forward+backward 35 "forward + backward" "${1:-}"
  local i=0 a
  for a in "${avatars[@]}"; do
    i=$((i + 1))
    summary "playback-$i" 16.6667 "playback $(basename "$a")" "${1:-}"
  done
}
avatars=("$@")
echo "all rounds:"
summaries
# The rounds at the machine's full speed: probe within 10 % of the fastest round's.
fastest=$(awk '{print $2}' "$work/probes" | sort -g | head -1)
awk -v f="$fastest" '$2 <= 1.1 * f {print $1}' "$work/probes" >"$work/full"
echo
echo "machine speed probe over the rounds: fastest $fastest ms, slowest $(awk '{print $2}' \
  "$work/probes" | sort -g | tail -1) ms; $(wc -l <"$work/full") of $rounds rounds within 10 % of \
the fastest (the machine at its full speed):"
summaries "$work/full"
