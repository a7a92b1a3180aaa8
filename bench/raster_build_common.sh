# Sourced by bench/raster_static_build.sh and bench/raster_cuda_build.sh (from the repository's
# root, with `obj` set): the compiler flags of the CMake build's Release rasterizer, a `compile`
# that runs as many compilers as there are cores, and `compile_rasterizer`, which compiles the
# rasterizer's sources (without FMA contraction, as CMake does) and the few others it needs into
# $obj and lists the objects in `lib`. `wait_all` waits for every compiler started.
flags=(-std=c++20 -O3 -DNDEBUG -fopenmp -fno-math-errno -Wall -Wextra -Wno-psabi -Isrc -Itests
       -isystem /usr/include/eigen3)
pids=()
compile() {  # source object [extra flags]
  g++ "${flags[@]}" "${@:3}" -c "$1" -o "$2" &
  pids+=($!)
  if [ ${#pids[@]} -ge "$(nproc)" ]; then wait "${pids[0]}"; pids=("${pids[@]:1}"); fi
}
wait_all() {
  for p in "${pids[@]}"; do wait "$p"; done
  pids=()
}
lib=()
compile_rasterizer() {
  local f o
  for f in src/raster/*.cpp; do
    o=$obj/raster_$(basename "$f" .cpp).o
    compile "$f" "$o" -ffp-contract=off
    lib+=("$o")
  done
  for f in src/core/camera.cpp src/core/fileio.cpp src/gaussians/ply.cpp; do
    o=$obj/$(basename "$(dirname "$f")")_$(basename "$f" .cpp).o
    compile "$f" "$o"
    lib+=("$o")
  done
}
