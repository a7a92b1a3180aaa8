#!/usr/bin/env bash
# SinGS's ablation on an imperfect prior: Laplacian (semantic / uniform / none) x density control
# (gpdc / naive), each trained on a synth subject's train/ with --perturb (colour drift, pose
# jitter, small warps) and evaluated on its clean test/ split (novel poses x 4 views, full
# resolution). Every cell is run with several trainer seeds; the table gives the medians.
# Usage: scripts/ablation.sh [path/to/kinesplat] [output dir]
# Tunables (environment): KS_ABL_SUBJECT (synth seed, 0), KS_ABL_SEEDS (trainer seeds, "0 1 2"),
# KS_ABL_ARGS (extra reconstruct options, e.g. "--iters 400"), KS_ABL_LAPLACIAN ("semantic uniform
# none"), KS_ABL_DENSITY ("gpdc naive").
# Output: OUT/table.md (markdown table of medians), OUT/runs.tsv (one line per run), the avatars
# and per-run metrics JSON.
set -euo pipefail

KS=${1:-build/kinesplat}
OUT=${2:-ablation-out}
SUBJECT_SEED=${KS_ABL_SUBJECT:-0}
SEEDS=${KS_ABL_SEEDS:-0 1 2}
EXTRA=${KS_ABL_ARGS:-}
LAPS=${KS_ABL_LAPLACIAN:-semantic uniform none}
DENS=${KS_ABL_DENSITY:-gpdc naive}

if [ ! -x "$KS" ]; then
  echo "ablation: $KS not found or not executable (run 'make build' first)" >&2
  exit 1
fi
mkdir -p "$OUT"
SUBJECT="$OUT/syn$SUBJECT_SEED"
if [ ! -f "$SUBJECT/train/dataset.json" ]; then
  "$KS" synth --seed "$SUBJECT_SEED" --out "$SUBJECT"
fi

RUNS="$OUT/runs.tsv"
printf 'laplacian\tdensity\tseed\tpsnr\tssim\tmasked_psnr\tmasked_ssim\tgaussians\tseconds\n' > "$RUNS"
for lap in $LAPS; do
  for den in $DENS; do
    for s in $SEEDS; do
      name="$lap-$den-s$s"
      echo "== ablation: $name"
      t0=$(date +%s)
      # shellcheck disable=SC2086
      "$KS" reconstruct "$SUBJECT/train" --out "$OUT/$name.ksavatar" --perturb --seed "$s" \
        --laplacian "$lap" --density "$den" -q $EXTRA \
        --eval "$SUBJECT/test" --eval-out "$OUT/$name.json" | tee "$OUT/$name.log"
      t1=$(date +%s)
      # "avatar: X (N Gaussians)" and
      # "eval: PSNR a SSIM b | masked PSNR c SSIM d (n frames)"
      awk -v lap="$lap" -v den="$den" -v s="$s" -v secs=$((t1 - t0)) '
        /^avatar:/ { g = $3; sub(/^\(/, "", g) }
        /^eval:/ { p = $3; q = $5; mp = $9; mq = $11 }
        END { printf "%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n", lap, den, s, p, q, mp, mq, g, secs }' \
        "$OUT/$name.log" >> "$RUNS"
    done
  done
done

# Medians per cell.
awk -F'\t' '
  function median(list,   a, n, t, i, j) {
    n = split(list, a, " ")
    for (i = 2; i <= n; i++) { t = a[i]; j = i - 1; while (j > 0 && a[j] + 0 > t + 0) { a[j + 1] = a[j]; j-- } a[j + 1] = t }
    return n % 2 ? a[(n + 1) / 2] : (a[n / 2] + a[n / 2 + 1]) / 2
  }
  NR > 1 {
    key = $1 "\t" $2; if (!(key in seen)) { seen[key] = 1; keys[++nk] = key }
    p[key] = p[key] " " $4; q[key] = q[key] " " $5; mp[key] = mp[key] " " $6; mq[key] = mq[key] " " $7
    g[key] = g[key] " " $8; t[key] = t[key] " " $9; cnt[key]++
  }
  END {
    print "| Laplacian | density | runs | masked PSNR (dB) | masked SSIM | full PSNR (dB) | full SSIM | Gaussians | seconds |"
    print "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    for (i = 1; i <= nk; i++) {
      k = keys[i]; split(k, kk, "\t")
      printf "| %s | %s | %d | %.2f | %.4f | %.2f | %.4f | %d | %d |\n", kk[1], kk[2], cnt[k],
        median(mp[k]), median(mq[k]), median(p[k]), median(q[k]), median(g[k]), median(t[k])
    }
  }' "$RUNS" > "$OUT/table.md"
echo
echo "== ablation medians (test split of synth seed $SUBJECT_SEED, --perturb training):"
cat "$OUT/table.md"
