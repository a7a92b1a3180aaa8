#!/bin/bash
# gsplat's rasterization (forward, forward + backward) on a scene of kinesplat's bench, on the
# same GPU as `kinesplat bench raster --device cuda` (docs/rasterizer_cuda.md, "Side by side
# with gsplat"). Outside CI; nothing of gsplat is committed. It needs a GPU machine with python3,
# PyTorch (CUDA), numpy, nvcc and ninja, and gsplat's source tree with GLM in
# gsplat/cuda/csrc/third_party/glm (a clone with --recursive), whose JIT build it starts
# (3DGS kernels for 3 channels only, for the GPU at hand: about 100 s on 16 cores).
#   GSPLAT_SRC=path/to/gsplat bench/gsplat_compare.sh SCENE.ply CAMERA.json [frames=50]
# The scene and camera: kinesplat bench raster --frames 1 --save-ply S.ply --save-camera C.json
# (with --gaussians / --width / --height as timed). OUT=dir keeps the image and a JSON summary.
set -u
if [ $# -lt 2 ] || [ -z "${GSPLAT_SRC:-}" ]; then
  echo "usage: GSPLAT_SRC=path/to/gsplat $0 SCENE.ply CAMERA.json [frames=50]" >&2
  exit 2
fi
here=$(cd "$(dirname "$0")" && pwd)
export PYTHONPATH="$GSPLAT_SRC${PYTHONPATH:+:$PYTHONPATH}" PYTHONUNBUFFERED=1
export MAX_JOBS=${MAX_JOBS:-$(nproc)} TORCH_EXTENSIONS_DIR=${TORCH_EXTENSIONS_DIR:-/tmp/torch_ext}
# gsplat's own reduced configuration (its documentation build): 3DGS, 3 channels.
export NUM_CHANNELS=3 BUILD_3DGUT=0 BUILD_2DGS=0 BUILD_ADAM=0 BUILD_RELOC=0 BUILD_LOSSES=0 \
  BUILD_CAMERA_WRAPPERS=0
if [ -z "${TORCH_CUDA_ARCH_LIST:-}" ]; then
  TORCH_CUDA_ARCH_LIST=$(nvidia-smi --query-gpu=compute_cap --format=csv,noheader | head -1)
  export TORCH_CUDA_ARCH_LIST
fi
export GSPLAT_COMMIT=${GSPLAT_COMMIT:-$(git -C "$GSPLAT_SRC" rev-parse HEAD 2>/dev/null || echo "?")}
mkdir -p "$TORCH_EXTENSIONS_DIR"
exec python3 "$here/gsplat_compare/bench_gsplat.py" "$1" "$2" "${3:-50}"
