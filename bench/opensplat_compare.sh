#!/usr/bin/env bash
# Side by side: kinesplat's CPU rasterizer against OpenSplat's CPU path on the same scene.
#
#   bench/opensplat_compare.sh [OPENSPLAT_SRC]
#
# OPENSPLAT_SRC (argument or environment variable): an OpenSplat checkout (measured at 15b7e80).
# This script downloads nothing and is not part of `make test` or CI. It needs Debian's
# libtorch-dev (bench-time only: `apt-get install libtorch-dev`) and a built kinesplat.
#
# What it does, in a build directory outside the repository (OS_BUILD_DIR):
#   1. configures OpenSplat with its own CMake, -DGPU_RUNTIME=CPU, Release, FetchContent fully
#      disconnected: its three FetchContent dependencies are replaced by small generated CMake
#      directories (FETCHCONTENT_SOURCE_DIR_*) that declare header-only targets over the system
#      headers; only its CPU rasterizer library (gsplat_cpu) is built, which uses none of them;
#   2. builds bench/opensplat_compare/driver.cpp (ours) against that library, OpenSplat's
#      autograd wrappers (project_gaussians.cpp, rasterize_gaussians.cpp) and libtorch;
#   3. makes the scene with `kinesplat bench raster --save-ply --save-camera` and renders it with
#      `kinesplat render` (the driver reports the PSNR of its forward image against it);
#   4. times forward + backward per step on 1 and 2 threads, RUNS times each, both sides on the
#      same .ply and camera, and prints the medians and the ratio.
# Nothing of OpenSplat is modified or copied.
#
# Environment: OS_BUILD_DIR (default ${TMPDIR:-/tmp}/kinesplat-opensplat-compare), KINESPLAT
# (default build/kinesplat; the driver links the libkinesplat_lib.a beside it, or KINESPLAT_LIB),
# GAUSSIANS (100000), SIZE (512), STEPS (timed steps per run, 10),
# RUNS (5), THREADS ("1 2"), KS_LOCK (a file: the builds, and the timings of each thread count,
# hold `flock KS_LOCK`),
# JOBS (build parallelism, 2).
set -euo pipefail

repo=$(cd "$(dirname "$0")/.." && pwd)
src=${1:-${OPENSPLAT_SRC:-}}
[ -n "$src" ] || { echo "usage: $0 OPENSPLAT_SRC (or set OPENSPLAT_SRC)" >&2; exit 2; }
src=$(cd "$src" && pwd)
[ -f "$src/rasterizer/gsplat-cpu/gsplat_cpu.cpp" ] ||
  { echo "error: $src is not an OpenSplat checkout (no rasterizer/gsplat-cpu)" >&2; exit 2; }
build=${OS_BUILD_DIR:-${TMPDIR:-/tmp}/kinesplat-opensplat-compare}
case "$build/" in "$repo"/*) echo "error: OS_BUILD_DIR must be outside the repository" >&2; exit 2 ;; esac
ks=${KINESPLAT:-$repo/build/kinesplat}
[ -x "$ks" ] || { echo "error: $ks not built (make build)" >&2; exit 2; }
kslib=${KINESPLAT_LIB:-$(dirname "$ks")/libkinesplat_lib.a}
[ -f "$kslib" ] || { echo "error: $kslib not found (make build; or set KINESPLAT_LIB)" >&2; exit 2; }
gaussians=${GAUSSIANS:-100000}
size=${SIZE:-512}
steps=${STEPS:-10}
runs=${RUNS:-5}
threads_list=${THREADS:-1 2}
jobs=${JOBS:-2}
# The lock is held once for steps 1-3 (the builds and the scene) and once per thread count for
# the timings (all RUNS of both renderers, a few minutes).
if [ -n "${KS_LOCK:-}" ]; then exec 9>>"$KS_LOCK"; fi
hold() { if [ -n "${KS_LOCK:-}" ]; then flock "$1" 9; fi; }

mkdir -p "$build"
rev=$(git -C "$src" rev-parse --short HEAD 2>/dev/null || echo unknown)
echo "OpenSplat source: $src (commit $rev); build dir: $build"

hold -x
# 1. OpenSplat, CPU runtime, offline. The generated stand-ins only declare the target names its
# CMakeLists links (the app, which is not built here); the headers are the system's.
shims=$build/fetchcontent-shims
for name in nlohmann_json nanoflann cxxopts; do
  mkdir -p "$shims/$name"
  cat >"$shims/$name/CMakeLists.txt" <<EOF
cmake_minimum_required(VERSION 3.21)
project(${name}_system_headers LANGUAGES CXX)
add_library($name INTERFACE)
add_library($name::$name ALIAS $name)
EOF
done
cmake -S "$src" -B "$build/opensplat" -DGPU_RUNTIME=CPU -DCMAKE_BUILD_TYPE=Release \
  -DFETCHCONTENT_FULLY_DISCONNECTED=ON \
  -DFETCHCONTENT_SOURCE_DIR_NLOHMANN_JSON="$shims/nlohmann_json" \
  -DFETCHCONTENT_SOURCE_DIR_NANOFLANN="$shims/nanoflann" \
  -DFETCHCONTENT_SOURCE_DIR_CXXOPTS="$shims/cxxopts" >"$build/opensplat-configure.log" 2>&1 ||
  { tail -30 "$build/opensplat-configure.log"; exit 1; }
cmake --build "$build/opensplat" --target gsplat_cpu -j "$jobs" >"$build/opensplat-build.log" 2>&1 ||
  { tail -30 "$build/opensplat-build.log"; exit 1; }
lib=$build/opensplat/libgsplat_cpu.a
[ -f "$lib" ] || { echo "error: $lib was not built" >&2; exit 1; }

# 2. The driver.
cmake -S "$repo/bench/opensplat_compare" -B "$build/driver" -DCMAKE_BUILD_TYPE=Release \
  -DOPENSPLAT_SRC="$src" -DGSPLAT_CPU_LIB="$lib" -DKINESPLAT_LIB="$kslib" \
  >"$build/driver-configure.log" 2>&1 ||
  { tail -30 "$build/driver-configure.log"; exit 1; }
cmake --build "$build/driver" -j "$jobs" >"$build/driver-build.log" 2>&1 ||
  { tail -30 "$build/driver-build.log"; exit 1; }
driver=$build/driver/opensplat_driver

# 3. The scene, and kinesplat's image of it.
scene=$build/scene.ply cam=$build/cam.json
"$ks" bench raster --gaussians "$gaussians" --width "$size" --height "$size" --frames 1 \
  --save-ply "$scene" --save-camera "$cam" >/dev/null
"$ks" render "$scene" --camera "$cam" --out "$build/kinesplat.png" --bits 16
OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 "$driver" --ply "$scene" --camera "$cam" --threads 1 \
  --steps 1 --warmup 0 --out "$build/opensplat.png" --compare "$build/kinesplat.png" |
  grep PSNR
hold -u

# 4. Timings: per step, median over STEPS within a run, then the median over RUNS. Each run's
# full output is kept in the build directory (kinesplat-T-R.txt, opensplat-T-R.txt).
median() { sort -g | awk '{v[NR]=$1} END {print (NR%2 ? v[(NR+1)/2] : (v[NR/2]+v[NR/2+1])/2)}'; }
field() { sed -n "s/^$1: median \([0-9.]*\) ms.*/\1/p" "$2"; }
declare -A med
for t in $threads_list; do
  declare -A runs_of=()
  hold -x
  for r in $(seq "$runs"); do
    kout=$build/kinesplat-$t-$r.txt oout=$build/opensplat-$t-$r.txt
    OMP_NUM_THREADS=$t "$ks" bench raster --ply "$scene" --camera "$cam" --backward \
      --frames "$steps" --threads "$t" >"$kout"
    OMP_NUM_THREADS=$t MKL_NUM_THREADS=$t "$driver" --ply "$scene" --camera "$cam" \
      --threads "$t" --steps "$steps" --warmup 1 >"$oout"
    for m in forward forward+backward; do
      runs_of[ks $m]+="$(field "$m" "$kout")"$'\n'
      runs_of[os $m]+="$(field "$m" "$oout")"$'\n'
      runs_of[ratio $m]+="$(awk -v a="$(field "$m" "$oout")" -v b="$(field "$m" "$kout")" \
        'BEGIN {print a / b}')"$'\n'
    done
    echo "threads $t run $r: forward kinesplat $(field forward "$kout") ms, OpenSplat" \
      "$(field forward "$oout") ms; forward+backward kinesplat $(field forward+backward "$kout")" \
      "ms, OpenSplat $(field forward+backward "$oout") ms"
  done
  hold -u
  for key in "${!runs_of[@]}"; do med[$t $key]=$(printf '%s' "${runs_of[$key]}" | median); done
  unset runs_of
done

echo
echo "$gaussians Gaussians, ${size}x${size}, per step: median over $runs runs of the median of $steps steps"
echo "(ratio: of the two medians; run ratio: the median of each run's ratio, its two sides timed"
echo "one after the other, which a machine whose speed drifts between runs moves less)"
printf '%-8s %-18s %14s %14s %8s %10s\n' threads pass "kinesplat ms" "OpenSplat ms" ratio \
  "run ratio"
for t in $threads_list; do
  for m in forward forward+backward; do
    k=${med[$t ks $m]} o=${med[$t os $m]}
    printf '%-8s %-18s %14.1f %14.1f %7.1fx %9.1fx\n' "$t" "$m" "$k" "$o" \
      "$(awk -v a="$o" -v b="$k" 'BEGIN {print a / b}')" "${med[$t ratio $m]}"
  done
done
