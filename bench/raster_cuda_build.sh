#!/bin/bash
# A raster-only build with the CUDA rasterizer, for a GPU machine that has nvcc but none of the
# project's packages (no OpenCV, Ceres, ...): it needs only the rasterizer's sources, Eigen,
# nlohmann-json and CLI11 headers, GoogleTest's static library and libgomp's (both linked in),
# and CUDA's static runtime. It builds
#   OUT/kinesplat          the command line with its `bench` command alone (the same sources as
#                          the full build's: kinesplat bench raster --device cuda ...)
#   OUT/raster_cuda_tests  the CUDA rasterizer's and posing's tests (tests/raster_cuda/) and the
#                          CPU rasterizer's
# The binaries load the machine's own libc and CUDA driver; the C++ runtime is linked in.
#   bench/raster_cuda_build.sh [out-dir=build-cuda] [cuda-architectures=90]
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-build-cuda}
archs=${2:-90}
obj=$out/obj
mkdir -p "$obj"
nvcc=${NVCC:-nvcc}
gencode=()
for a in ${archs//,/ }; do gencode+=(-gencode "arch=compute_$a,code=sm_$a"); done
source bench/raster_build_common.sh
compile_rasterizer
for f in src/raster_cuda/*.cu; do
  o=$obj/$(basename "$f" .cu).o
  "$nvcc" -std=c++17 -O3 -DNDEBUG "${gencode[@]}" -Isrc -isystem /usr/include/eigen3 \
    -Xcompiler -Wall,-Wextra,-fopenmp -c "$f" -o "$o" &
  pids+=($!)
  lib+=("$o")
done
cli=()
for f in src/cli/main.cpp src/cli/bench_cmd.cpp; do
  o=$obj/cli_$(basename "$f" .cpp).o
  compile "$f" "$o"
  cli+=("$o")
done
tests=()
for f in src/body/lbs.cpp; do
  o=$obj/body_$(basename "$f" .cpp).o
  compile "$f" "$o"
  lib+=("$o")
done
for f in tests/raster_cuda/rasterizer_cuda_test.cpp tests/raster_cuda/lbs_cuda_test.cpp \
  tests/raster/raster_test.cpp; do
  o=$obj/test_$(basename "$f" .cpp).o
  compile "$f" "$o" -DKS_CLI_PATH=\"none\" -DKS_SOURCE_DIR=\"none\"
  tests+=("$o")
done
wait_all
cudart=$(dirname "$(command -v "$nvcc")")/../lib64/libcudart_static.a
gomp=$(g++ -print-file-name=libgomp.a)
link() {
  g++ -static-libstdc++ -static-libgcc "$@" "$gomp" "$cudart" -ldl -lrt -lpthread
}
link -o "$out/kinesplat" "${cli[@]}" "${lib[@]}"
link -o "$out/raster_cuda_tests" "${tests[@]}" "${lib[@]}" /usr/lib/x86_64-linux-gnu/libgtest_main.a \
  /usr/lib/x86_64-linux-gnu/libgtest.a
echo "built $out/kinesplat and $out/raster_cuda_tests (CUDA architectures: $archs)"
