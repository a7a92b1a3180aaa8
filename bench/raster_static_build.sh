#!/bin/bash
# Static, raster-only builds of the rasterizer's tests and of bench/raster_kernels.cpp, for a
# machine that has none of the project's packages (no OpenCV, Ceres, ...): they need only the
# rasterizer's own sources, Eigen and nlohmann-json headers, GoogleTest's static library and
# libgomp. Release flags as the CMake build; the rasterizer's sources without FMA contraction.
#   bench/raster_static_build.sh [out-dir=build-static]
# then, on the other machine: OUT/raster_tests; OUT/raster_kernels avx2 20; ... (docs/rasterizer.md)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-build-static}
obj=$out/obj
mkdir -p "$obj"
source bench/raster_build_common.sh
compile_rasterizer
tests=()
for f in tests/raster/raster_test.cpp tests/raster/preprocess_simd_test.cpp \
         tests/raster/projection_test.cpp tests/core/aligned_test.cpp; do
  o=$obj/test_$(basename "$f" .cpp).o
  compile "$f" "$o" -DKS_CLI_PATH=\"none\" -DKS_SOURCE_DIR=\"none\"
  tests+=("$o")
done
compile bench/raster_kernels.cpp "$obj/raster_kernels.o"
wait_all
# libgomp's and GoogleTest's static archives warn that dlopen / getaddrinfo would need the build
# machine's glibc at run time (neither is called here): the linker's output is shown on failure.
link() {
  local log
  if ! log=$(g++ -static -fopenmp "$@" -lpthread 2>&1); then
    echo "$log" >&2
    return 1
  fi
}
link -o "$out/raster_tests" "${lib[@]}" "${tests[@]}" /usr/lib/x86_64-linux-gnu/libgtest_main.a \
  /usr/lib/x86_64-linux-gnu/libgtest.a
link -o "$out/raster_kernels" "${lib[@]}" "$obj/raster_kernels.o"
echo "built $out/raster_tests and $out/raster_kernels"
