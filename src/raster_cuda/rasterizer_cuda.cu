// The CUDA rasterizer (rasterizer_cuda.hpp): the CPU rasterizer's passes as kernels, in the
// The compiler sees no Eigen device annotations (the kernels use their own small arithmetic).
#define EIGEN_NO_CUDA
// order of 3DGS's rasterizer_impl.cu and gsplat's ops:
//   project      one thread a Gaussian: culling, EWA covariance, conic, the exact alpha box,
//                radius, SH colour; its tile rectangle and the number of tiles it touches
//   scan         exclusive sum of those counts (CUB): each Gaussian's first list entry
//   duplicate    one key a (tile, Gaussian): tile << 32 | depth bits, value the Gaussian's id
//   sort         CUB's radix sort over the key bits in use (stable: ties keep id order)
//   ranges       each tile's [start, end) in the sorted list
//   composite    one block of 16 x 16 threads a tile, the tile's Gaussians staged in shared
//                memory 256 at a time, front to back, until every pixel is finished
//   backward     the same blocks back to front from each pixel's last contributor; per Gaussian
//                the warp's 32 pixels' gradients summed by shuffles, one atomic add a warp
//   chain rule   one thread a Gaussian: screen-space gradients to the raw parameters
// The per-Gaussian arithmetic is projection.hpp's and sh.hpp's, written out for the device (the
// CPU's templates use Eigen); the tests compare both (tests/raster_cuda/).
#include <cuda_runtime.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cub/device/device_radix_sort.cuh>
#include <cub/device/device_scan.cuh>
#include <initializer_list>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/parallel_copy.hpp"
#include "raster_cuda/lbs_cuda.cuh"
#include "raster_cuda/rasterizer_cuda.hpp"

namespace ks::cuda {

namespace {

constexpr int kTile = 16;
constexpr int kBlock = kTile * kTile;
constexpr int kNG = 9;  // screen-space gradients a Gaussian: mx, my, a, b, c, opacity, r, g, b

void check(cudaError_t e, const char* what) {
  if (e != cudaSuccess)
    throw Error(std::string("CUDA rasterizer: ") + what + ": " + cudaGetErrorString(e));
}

// A device array that only grows.
template <class T>
struct DeviceArray {
  T* p = nullptr;
  size_t cap = 0;
  size_t n = 0;
  DeviceArray() = default;
  DeviceArray(const DeviceArray&) = delete;
  DeviceArray& operator=(const DeviceArray&) = delete;
  ~DeviceArray() {
    if (p) cudaFree(p);
  }
  void resize(size_t count) {
    if (count > cap) {
      if (p) check(cudaFree(p), "cudaFree");
      p = nullptr;
      const size_t c = std::max<size_t>(count + count / 4, 1);
      check(cudaMalloc(&p, c * sizeof(T)), "cudaMalloc");
      cap = c;
    }
    n = count;
  }
  void upload(const std::vector<T>& v, cudaStream_t s) {
    resize(v.size());
    if (!v.empty())
      check(cudaMemcpyAsync(p, v.data(), v.size() * sizeof(T), cudaMemcpyHostToDevice, s),
            "copy to the device");
  }
  void download(std::vector<T>& v, cudaStream_t s) const {
    v.resize(n);
    if (n)
      check(cudaMemcpyAsync(v.data(), p, n * sizeof(T), cudaMemcpyDeviceToHost, s),
            "copy from the device");
  }
};

// Page-locked host memory that the large per-step copies go through: a copy from pageable
// memory is staged by the driver through a small pinned buffer at a fraction of the bus's
// speed; here the host side is copied over the threads into this buffer (or out of it) and the
// device copies it at the bus's speed. Grows only; `done` marks the last copies out of it.
struct PinnedStage {
  unsigned char* p = nullptr;
  size_t cap = 0;
  cudaEvent_t done = nullptr;
  PinnedStage() = default;
  PinnedStage(const PinnedStage&) = delete;
  PinnedStage& operator=(const PinnedStage&) = delete;
  ~PinnedStage() {
    if (done) cudaEventSynchronize(done), cudaEventDestroy(done);
    if (p) cudaFreeHost(p);
  }
  // At least `bytes`, once the copies queued from it before have finished.
  unsigned char* get(size_t bytes) {
    if (done) check(cudaEventSynchronize(done), "pinned stage");
    if (bytes > cap) {
      if (p) check(cudaFreeHost(p), "cudaFreeHost");
      p = nullptr;
      cap = 0;
      const size_t c = std::max<size_t>(bytes + bytes / 4, 1);
      check(cudaHostAlloc(reinterpret_cast<void**>(&p), c, cudaHostAllocDefault), "cudaHostAlloc");
      cap = c;
    }
    return p;
  }
};

// One host array to the device or back through the stage.
struct Span {
  const void* src;
  void* dst;
  size_t bytes;
};
constexpr size_t stage_round(size_t b) {
  return (b + 255) & ~size_t(255);
}

// Host arrays -> device: copied into the stage over the threads, then queued on `stream`.
// The stage's room for these spans, each from a 256-byte boundary.
size_t stage_bytes(std::initializer_list<Span> spans) {
  size_t total = 0;
  for (const Span& x : spans) total += stage_round(x.bytes);
  return total;
}

void upload_spans(PinnedStage& stage, cudaStream_t stream, std::initializer_list<Span> spans) {
  unsigned char* st = stage.get(stage_bytes(spans));
  size_t off = 0;
  for (const Span& x : spans) {
    if (x.bytes) {
      parallel_copy(static_cast<const unsigned char*>(x.src), x.bytes, st + off);
      check(cudaMemcpyAsync(x.dst, st + off, x.bytes, cudaMemcpyHostToDevice, stream),
            "copy to the device");
    }
    off += stage_round(x.bytes);
  }
  if (!stage.done) check(cudaEventCreateWithFlags(&stage.done, cudaEventDisableTiming), "event");
  check(cudaEventRecord(stage.done, stream), "cudaEventRecord");
}

// Device arrays -> host: into the stage, then (after the stream's work) over the threads into
// the host arrays.
void download_spans(PinnedStage& stage, cudaStream_t stream, std::initializer_list<Span> spans) {
  unsigned char* st = stage.get(stage_bytes(spans));
  size_t off = 0;
  for (const Span& x : spans) {
    if (x.bytes)
      check(cudaMemcpyAsync(st + off, x.src, x.bytes, cudaMemcpyDeviceToHost, stream),
            "copy from the device");
    off += stage_round(x.bytes);
  }
  check(cudaStreamSynchronize(stream), "copy from the device");
  off = 0;
  for (const Span& x : spans) {
    if (x.bytes) parallel_copy(st + off, x.bytes, static_cast<unsigned char*>(x.dst));
    off += stage_round(x.bytes);
  }
}

// Span of a device array resized to a host vector's size (upload), or of a host vector resized
// to a device array's (download).
template <class T>
Span up(DeviceArray<T>& d, const std::vector<T>& v) {
  d.resize(v.size());
  return {v.data(), d.p, v.size() * sizeof(T)};
}
template <class T>
Span down(const DeviceArray<T>& d, std::vector<T>& v) {
  v.resize(d.n);
  return {d.p, v.data(), d.n * sizeof(T)};
}

// The camera as the kernels read it (projection.hpp's CameraT<float>).
struct Cam {
  float R[9];
  float t[3], centre[3];
  float fx, fy, cx, cy;
  float lox, hix, loy, hiy;
  int W, H;
};

Cam make_cam(const Camera& c) {
  Cam k;
  for (int r = 0; r < 3; ++r)
    for (int q = 0; q < 3; ++q) k.R[3 * r + q] = float(c.R(r, q));
  const Eigen::Vector3d ce = c.centre();
  for (int r = 0; r < 3; ++r) k.t[r] = float(c.t[r]), k.centre[r] = float(ce[r]);
  k.fx = float(c.fx), k.fy = float(c.fy), k.cx = float(c.cx), k.cy = float(c.cy);
  k.W = c.width, k.H = c.height;
  k.lox = (-0.15f * float(k.W) - k.cx) / k.fx;
  k.hix = (1.15f * float(k.W) - k.cx) / k.fx;
  k.loy = (-0.15f * float(k.H) - k.cy) / k.fy;
  k.hiy = (1.15f * float(k.H) - k.cy) / k.fy;
  return k;
}

// ---- small 3 x 3 arithmetic (row-major)
struct M3 {
  float m[9];
  __device__ float& operator()(int r, int c) { return m[3 * r + c]; }
  __device__ float operator()(int r, int c) const { return m[3 * r + c]; }
};

__device__ inline M3 mul(const M3& a, const M3& b) {
  M3 o;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) o(r, c) = a(r, 0) * b(0, c) + a(r, 1) * b(1, c) + a(r, 2) * b(2, c);
  return o;
}

__device__ inline M3 transpose(const M3& a) {
  M3 o;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) o(r, c) = a(c, r);
  return o;
}

__device__ inline M3 quat_matrix(float w, float x, float y, float z) {
  M3 R;
  R(0, 0) = 1 - 2 * (y * y + z * z), R(0, 1) = 2 * (x * y - w * z), R(0, 2) = 2 * (x * z + w * y);
  R(1, 0) = 2 * (x * y + w * z), R(1, 1) = 1 - 2 * (x * x + z * z), R(1, 2) = 2 * (y * z - w * x);
  R(2, 0) = 2 * (x * z - w * y), R(2, 1) = 2 * (y * z + w * x), R(2, 2) = 1 - 2 * (x * x + y * y);
  return R;
}

// ---- spherical harmonics (sh.hpp's constants and signs)
__device__ inline void sh_basis(int deg, float x, float y, float z, float* b) {
  b[0] = 0.28209479177387814f;
  if (deg < 1) return;
  const float C1 = 0.4886025119029199f;
  b[1] = -C1 * y, b[2] = C1 * z, b[3] = -C1 * x;
  if (deg < 2) return;
  const float xx = x * x, yy = y * y, zz = z * z;
  b[4] = 1.0925484305920792f * x * y;
  b[5] = -1.0925484305920792f * y * z;
  b[6] = 0.31539156525252005f * (2 * zz - xx - yy);
  b[7] = -1.0925484305920792f * x * z;
  b[8] = 0.5462742152960396f * (xx - yy);
  if (deg < 3) return;
  b[9] = -0.5900435899266435f * y * (3 * xx - yy);
  b[10] = 2.890611442640554f * x * y * z;
  b[11] = -0.4570457994644658f * y * (4 * zz - xx - yy);
  b[12] = 0.3731763325901154f * z * (2 * zz - 3 * xx - 3 * yy);
  b[13] = -0.4570457994644658f * x * (4 * zz - xx - yy);
  b[14] = 1.445305721320277f * z * (xx - yy);
  b[15] = -0.5900435899266435f * x * (xx - 3 * yy);
}

__device__ inline void sh_basis_grad(int deg, float x, float y, float z, float* bx, float* by,
                                     float* bz) {
  bx[0] = by[0] = bz[0] = 0;
  if (deg < 1) return;
  const float C1 = 0.4886025119029199f;
  bx[1] = 0, by[1] = -C1, bz[1] = 0;
  bx[2] = 0, by[2] = 0, bz[2] = C1;
  bx[3] = -C1, by[3] = 0, bz[3] = 0;
  if (deg < 2) return;
  const float xx = x * x, yy = y * y, zz = z * z;
  const float c20 = 1.0925484305920792f, c21 = -1.0925484305920792f, c22 = 0.31539156525252005f,
              c23 = -1.0925484305920792f, c24 = 0.5462742152960396f;
  bx[4] = c20 * y, by[4] = c20 * x, bz[4] = 0;
  bx[5] = 0, by[5] = c21 * z, bz[5] = c21 * y;
  bx[6] = -2 * c22 * x, by[6] = -2 * c22 * y, bz[6] = 4 * c22 * z;
  bx[7] = c23 * z, by[7] = 0, bz[7] = c23 * x;
  bx[8] = 2 * c24 * x, by[8] = -2 * c24 * y, bz[8] = 0;
  if (deg < 3) return;
  const float c30 = -0.5900435899266435f, c31 = 2.890611442640554f, c32 = -0.4570457994644658f,
              c33 = 0.3731763325901154f, c34 = -0.4570457994644658f, c35 = 1.445305721320277f,
              c36 = -0.5900435899266435f;
  bx[9] = c30 * 6 * x * y, by[9] = c30 * (3 * xx - 3 * yy), bz[9] = 0;
  bx[10] = c31 * y * z, by[10] = c31 * x * z, bz[10] = c31 * x * y;
  bx[11] = c32 * (-2 * x * y), by[11] = c32 * (4 * zz - xx - 3 * yy), bz[11] = c32 * 8 * y * z;
  bx[12] = c33 * (-6 * x * z), by[12] = c33 * (-6 * y * z),
  bz[12] = c33 * (6 * zz - 3 * xx - 3 * yy);
  bx[13] = c34 * (4 * zz - 3 * xx - yy), by[13] = c34 * (-2 * x * y), bz[13] = c34 * 8 * x * z;
  bx[14] = c35 * 2 * x * z, by[14] = c35 * (-2 * y * z), bz[14] = c35 * (xx - yy);
  bx[15] = c36 * (3 * xx - 3 * yy), by[15] = c36 * (-6 * x * y), bz[15] = 0;
}

// The render record a visible Gaussian: xy_o = (u, v, opacity, depth), conic = (a, b, c, clamp
// bits as a float), rgb = (r, g, b, 0).
struct Records {
  float4* xy_o;
  float4* conic;
  float4* rgb;
};

__device__ inline void camera_point(const Cam& c, const float* m, float* p) {
  for (int r = 0; r < 3; ++r)
    p[r] = c.R[3 * r] * m[0] + c.R[3 * r + 1] * m[1] + c.R[3 * r + 2] * m[2] + c.t[r];
}

// The EWA Jacobian's product T = J W (2 x 3) at the camera-space point p, with x/z and y/z
// clamped as on the CPU; ux, uy the clamped ratios.
__device__ inline void ewa_T(const Cam& c, const float* p, float* Tm, float& ux, float& uy) {
  const float z = p[2];
  ux = fminf(fmaxf(p[0] / z, c.lox), c.hix);
  uy = fminf(fmaxf(p[1] / z, c.loy), c.hiy);
  const float J00 = c.fx / z, J02 = -c.fx * ux / z, J11 = c.fy / z, J12 = -c.fy * uy / z;
  for (int q = 0; q < 3; ++q) {
    Tm[q] = J00 * c.R[q] + J02 * c.R[6 + q];
    Tm[3 + q] = J11 * c.R[3 + q] + J12 * c.R[6 + q];
  }
}

// S3 = M M^T with M = R(q / |q|) diag(exp(log_scale)); false when |q| <= 1e-12.
__device__ inline bool cov3d(const float* q, const float* ls, M3& S) {
  const float qn = sqrtf(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  if (!(qn > 1e-12f)) return false;
  const M3 R = quat_matrix(q[0] / qn, q[1] / qn, q[2] / qn, q[3] / qn);
  M3 M;
  for (int k = 0; k < 3; ++k) {
    const float s = expf(ls[k]);
    for (int r = 0; r < 3; ++r) M(r, k) = R(r, k) * s;
  }
  S = mul(M, transpose(M));
  return true;
}

__global__ void project_kernel(int N, int deg, const float* __restrict__ means,
                               const float* __restrict__ log_scales,
                               const float* __restrict__ quats, const float* __restrict__ logits,
                               const float* __restrict__ sh, Cam cam, float near, float low_pass,
                               Records rec, int* __restrict__ radii, float* __restrict__ depths,
                               uint2* __restrict__ tile_rect, uint32_t* __restrict__ touched) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= N) return;
  radii[i] = 0;
  touched[i] = 0;
  depths[i] = 0;
  const float m[3] = {means[3 * i], means[3 * i + 1], means[3 * i + 2]};
  float p[3];
  camera_point(cam, m, p);
  const float z = p[2];
  if (!(z >= near)) return;
  const float o = 1.f / (1.f + expf(-logits[i]));
  if (!(o >= 1.f / 255.f)) return;
  M3 S;
  if (!cov3d(&quats[4 * i], &log_scales[3 * i], S)) return;
  float Tm[6], ux, uy;
  ewa_T(cam, p, Tm, ux, uy);
  // S2 = T S T^T
  float TS[6];
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c)
      TS[3 * r + c] = Tm[3 * r] * S(0, c) + Tm[3 * r + 1] * S(1, c) + Tm[3 * r + 2] * S(2, c);
  const float A = TS[0] * Tm[0] + TS[1] * Tm[1] + TS[2] * Tm[2] + low_pass;
  const float B = TS[0] * Tm[3] + TS[1] * Tm[4] + TS[2] * Tm[5];
  const float C = TS[3] * Tm[3] + TS[4] * Tm[4] + TS[5] * Tm[5] + low_pass;
  const float det = A * C - B * B;
  if (!(det > 0)) return;
  const float u = cam.fx * p[0] / z + cam.cx, v = cam.fy * p[1] / z + cam.cy;
  const float L = fmaxf(0.f, logf(255.f * o));
  const float ex = sqrtf(2 * L * A) + 0.01f, ey = sqrtf(2 * L * C) + 0.01f;
  const float fx0 = ceilf(u - ex - 0.5f), fx1 = floorf(u + ex - 0.5f);
  const float fy0 = ceilf(v - ey - 0.5f), fy1 = floorf(v + ey - 0.5f);
  if (!(fx1 >= 0 && fy1 >= 0 && fx0 <= float(cam.W - 1) && fy0 <= float(cam.H - 1))) return;
  if (!(fx0 <= fx1 && fy0 <= fy1)) return;
  const int x0 = int(fmaxf(fx0, 0.f)), x1 = int(fminf(fx1, float(cam.W - 1)));
  const int y0 = int(fmaxf(fy0, 0.f)), y1 = int(fminf(fy1, float(cam.H - 1)));
  const int tx0 = x0 / kTile, tx1 = x1 / kTile, ty0 = y0 / kTile, ty1 = y1 / kTile;
  const float mid = 0.5f * (A + C);
  const float lam1 = mid + sqrtf(fmaxf(0.1f, mid * mid - det));
  radii[i] = max(1, int(ceilf(3.f * sqrtf(lam1))));
  depths[i] = z;
  tile_rect[i] =
      make_uint2(uint32_t(tx0) | uint32_t(tx1) << 16, uint32_t(ty0) | uint32_t(ty1) << 16);
  touched[i] = uint32_t((tx1 - tx0 + 1) * (ty1 - ty0 + 1));
  // Colour from SH along the unit direction from the camera centre to the mean.
  const float d[3] = {m[0] - cam.centre[0], m[1] - cam.centre[1], m[2] - cam.centre[2]};
  const float dist = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  float dir[3] = {0.f, 0.f, 1.f};
  if (dist > 0) dir[0] = d[0] / dist, dir[1] = d[1] / dist, dir[2] = d[2] / dist;
  float b[16];
  sh_basis(deg, dir[0], dir[1], dir[2], b);
  const int K = (deg + 1) * (deg + 1);
  const float* co = sh + size_t(i) * K * 3;
  float rgb[3];
  int bits = 0;
  for (int ch = 0; ch < 3; ++ch) {
    float c = 0.5f;
    for (int k = 0; k < K; ++k) c += b[k] * co[3 * k + ch];
    if (c < 0) bits |= 1 << ch;
    rgb[ch] = fmaxf(c, 0.f);
  }
  rec.xy_o[i] = make_float4(u, v, o, z);
  rec.conic[i] = make_float4(C / det, -B / det, A / det, float(bits));
  rec.rgb[i] = make_float4(rgb[0], rgb[1], rgb[2], 0.f);
}

__global__ void duplicate_kernel(int N, const uint2* __restrict__ tile_rect,
                                 const uint32_t* __restrict__ touched,
                                 const uint32_t* __restrict__ offsets,
                                 const float* __restrict__ depths, int tiles_x,
                                 uint64_t* __restrict__ keys, uint32_t* __restrict__ vals) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= N || touched[i] == 0) return;
  const uint2 r = tile_rect[i];
  const int tx0 = r.x & 0xffff, tx1 = r.x >> 16, ty0 = r.y & 0xffff, ty1 = r.y >> 16;
  const uint64_t dbits = __float_as_uint(depths[i]);  // positive: the bits sort as the values
  uint32_t k = offsets[i];
  for (int ty = ty0; ty <= ty1; ++ty)
    for (int tx = tx0; tx <= tx1; ++tx, ++k) {
      keys[k] = uint64_t(ty * tiles_x + tx) << 32 | dbits;
      vals[k] = uint32_t(i);
    }
}

__global__ void ranges_kernel(uint32_t M, const uint64_t* __restrict__ keys,
                              uint2* __restrict__ ranges) {
  const uint32_t k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= M) return;
  const uint32_t tile = uint32_t(keys[k] >> 32);
  if (k == 0 || uint32_t(keys[k - 1] >> 32) != tile) ranges[tile].x = k;
  if (k == M - 1 || uint32_t(keys[k + 1] >> 32) != tile) ranges[tile].y = k + 1;
}

struct Images {
  float* color;      // W H 3
  float* alpha;      // W H
  float* depth;      // W H (null: not asked for, RasterSettings::depth)
  float* final_T;    // W H (null: image only)
  uint32_t* n_last;  // W H: one past the last contributor's index in the tile's list
};

// The pixel this thread of a tile's block handles (row-major in the tile), whether it lies in
// the image, and its centre.
struct TilePixel {
  int px, py;
  bool inside;
  float cx, cy;
};
__device__ __forceinline__ TilePixel tile_pixel(int tile, int tiles_x, int W, int H) {
  const int px = (tile % tiles_x) * kTile + int(threadIdx.x) % kTile;
  const int py = (tile / tiles_x) * kTile + int(threadIdx.x) / kTile;
  return {px, py, px < W && py < H, float(px) + 0.5f, float(py) + 0.5f};
}

__global__ void __launch_bounds__(kBlock)
    composite_kernel(int W, int H, int tiles_x, const uint2* __restrict__ ranges,
                     const uint32_t* __restrict__ ids, Records rec, float3 bg, Images img) {
  const int tile = blockIdx.x;
  const auto [px, py, inside, cxp, cyp] = tile_pixel(tile, tiles_x, W, H);
  const uint2 range = ranges[tile];
  __shared__ float4 s_xy_o[kBlock];
  __shared__ float4 s_conic[kBlock];
  __shared__ float4 s_rgb[kBlock];
  bool done = !inside;
  float T = 1.f, c0 = 0.f, c1 = 0.f, c2 = 0.f, dsum = 0.f;
  uint32_t last = 0;
  const int total = int(range.y - range.x);
  for (int b0 = 0; b0 < total; b0 += kBlock) {
    if (__syncthreads_count(done) == kBlock) break;
    const int j = b0 + int(threadIdx.x);
    if (j < total) {
      const uint32_t g = ids[range.x + j];
      s_xy_o[threadIdx.x] = rec.xy_o[g];
      s_conic[threadIdx.x] = rec.conic[g];
      s_rgb[threadIdx.x] = rec.rgb[g];
    }
    __syncthreads();
    const int n = min(kBlock, total - b0);
    for (int k = 0; k < n && !done; ++k) {
      const float4 xo = s_xy_o[k], cn = s_conic[k];
      const float dx = xo.x - cxp, dy = xo.y - cyp;
      const float power = -0.5f * (cn.x * dx * dx + cn.z * dy * dy) - cn.y * dx * dy;
      if (power > 0.f) continue;
      const float a = fminf(0.99f, xo.z * __expf(power));
      if (a < 1.f / 255.f) continue;
      const float Tn = T * (1.f - a);
      if (Tn < 1e-4f) {
        done = true;
        continue;
      }
      const float w = a * T;
      const float4 col = s_rgb[k];
      c0 += col.x * w, c1 += col.y * w, c2 += col.z * w;
      dsum += xo.w * w;
      T = Tn;
      last = uint32_t(b0 + k + 1);
    }
  }
  if (!inside) return;
  const size_t pix = size_t(py) * W + px;
  img.color[3 * pix] = c0 + T * bg.x;
  img.color[3 * pix + 1] = c1 + T * bg.y;
  img.color[3 * pix + 2] = c2 + T * bg.z;
  img.alpha[pix] = 1.f - T;
  if (img.depth) img.depth[pix] = dsum;
  if (img.final_T) {
    img.final_T[pix] = T;
    img.n_last[pix] = last;
  }
}

__device__ inline float warp_sum(float v) {
  for (int o = 16; o > 0; o >>= 1) v += __shfl_down_sync(0xffffffffu, v, o);
  return v;
}

__global__ void __launch_bounds__(kBlock)
    backward_kernel(int W, int H, int tiles_x, const uint2* __restrict__ ranges,
                    const uint32_t* __restrict__ ids, Records rec, float3 bg, Images img,
                    const float* __restrict__ dL_dcolor, const float* __restrict__ dL_dalpha,
                    float* __restrict__ gscreen) {
  const int tile = blockIdx.x;
  const auto [px, py, inside, cxp, cyp] = tile_pixel(tile, tiles_x, W, H);
  const uint2 range = ranges[tile];
  __shared__ float4 s_xy_o[kBlock];
  __shared__ float4 s_conic[kBlock];
  __shared__ float4 s_rgb[kBlock];
  __shared__ uint32_t s_id[kBlock];
  const size_t pix = inside ? size_t(py) * W + px : 0;
  const float T_final = inside ? img.final_T[pix] : 1.f;
  float T = T_final;
  const uint32_t last = inside ? img.n_last[pix] : 0;
  float g0 = 0, g1 = 0, g2 = 0, gA = 0;
  if (inside) {
    g0 = dL_dcolor[3 * pix], g1 = dL_dcolor[3 * pix + 1], g2 = dL_dcolor[3 * pix + 2];
    if (dL_dalpha) gA = dL_dalpha[pix];
  }
  const float bg_dot = bg.x * g0 + bg.y * g1 + bg.z * g2;
  float acc0 = 0, acc1 = 0, acc2 = 0;  // colour of everything behind, per unit transmittance
  float last_a = 0, lc0 = 0, lc1 = 0, lc2 = 0;  // the Gaussian behind the current one
  // The largest last contributor in the block: nothing beyond it is visited.
  __shared__ uint32_t s_max_last;
  if (threadIdx.x == 0) s_max_last = 0;
  __syncthreads();
  atomicMax(&s_max_last, last);
  __syncthreads();
  const int total = int(s_max_last);
  const int lane = threadIdx.x & 31;
  for (int b_end = total; b_end > 0; b_end -= kBlock) {
    const int b0 = max(0, b_end - kBlock);
    __syncthreads();
    const int j = b0 + int(threadIdx.x);
    if (j < b_end) {
      const uint32_t g = ids[range.x + j];
      s_id[threadIdx.x] = g;
      s_xy_o[threadIdx.x] = rec.xy_o[g];
      s_conic[threadIdx.x] = rec.conic[g];
      s_rgb[threadIdx.x] = rec.rgb[g];
    }
    __syncthreads();
    for (int k = b_end - b0 - 1; k >= 0; --k) {
      const int idx = b0 + k;  // index in the tile's list
      float v[kNG] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
      bool valid = false;
      const float4 xo = s_xy_o[k], cn = s_conic[k];
      if (inside && uint32_t(idx) < last) {
        const float dx = xo.x - cxp, dy = xo.y - cyp;
        const float power = -0.5f * (cn.x * dx * dx + cn.z * dy * dy) - cn.y * dx * dy;
        const float G = __expf(power);
        const float og = xo.z * G;
        const float a = fminf(0.99f, og);
        if (power <= 0.f && a >= 1.f / 255.f) {
          valid = true;
          T = T / (1.f - a);
          const float w = a * T;
          v[6] = w * g0, v[7] = w * g1, v[8] = w * g2;
          const float4 col = s_rgb[k];
          acc0 = last_a * lc0 + (1.f - last_a) * acc0;
          acc1 = last_a * lc1 + (1.f - last_a) * acc1;
          acc2 = last_a * lc2 + (1.f - last_a) * acc2;
          lc0 = col.x, lc1 = col.y, lc2 = col.z;
          last_a = a;
          float dL_da = ((col.x - acc0) * g0 + (col.y - acc1) * g1 + (col.z - acc2) * g2) * T;
          const float inv = 1.f / (1.f - a);
          dL_da += -T_final * inv * bg_dot + gA * T_final * inv;
          if (og <= 0.99f) {
            const float dG = xo.z * dL_da;  // dL/dG
            const float gp = dG * G;        // dL/dpower
            v[0] = gp * (-cn.x * dx - cn.y * dy);
            v[1] = gp * (-cn.z * dy - cn.y * dx);
            v[2] = gp * (-0.5f * dx * dx);
            v[3] = gp * (-dx * dy);
            v[4] = gp * (-0.5f * dy * dy);
            v[5] = G * dL_da;
          }
        }
      }
      // Sum over the warp's pixels, one atomic add a value where any pixel contributed.
      if (__any_sync(0xffffffffu, valid)) {
        for (int q = 0; q < kNG; ++q) v[q] = warp_sum(v[q]);
        if (lane == 0) {
          float* dst = gscreen + size_t(s_id[k]) * kNG;
          for (int q = 0; q < kNG; ++q) atomicAdd(dst + q, v[q]);
        }
      }
    }
  }
}

__global__ void chain_rule_kernel(int N, int deg, const float* __restrict__ means,
                                  const float* __restrict__ log_scales,
                                  const float* __restrict__ quats, const float* __restrict__ sh,
                                  Cam cam, const int* __restrict__ radii, Records rec,
                                  const float* __restrict__ gscreen, float* __restrict__ g_means,
                                  float* __restrict__ g_ls, float* __restrict__ g_q,
                                  float* __restrict__ g_logit, float* __restrict__ g_sh,
                                  float* __restrict__ g_m2d) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= N) return;
  const int K = (deg + 1) * (deg + 1);
  float gs[kNG];
  for (int q = 0; q < kNG; ++q) gs[q] = gscreen[size_t(i) * kNG + q];
  g_m2d[2 * i] = gs[0], g_m2d[2 * i + 1] = gs[1];
  float* gsh = g_sh + size_t(i) * K * 3;
  if (radii[i] == 0) {
    for (int q = 0; q < 3; ++q) g_means[3 * i + q] = 0, g_ls[3 * i + q] = 0;
    for (int q = 0; q < 4; ++q) g_q[4 * i + q] = 0;
    for (int q = 0; q < 3 * K; ++q) gsh[q] = 0;
    g_logit[i] = 0;
    return;
  }
  const float4 xo = rec.xy_o[i], cn = rec.conic[i];
  const float o = xo.z;
  g_logit[i] = gs[5] * o * (1 - o);
  const float m[3] = {means[3 * i], means[3 * i + 1], means[3 * i + 2]};
  // Colour -> SH coefficients and the view direction.
  float gmean[3] = {0, 0, 0};
  const float d[3] = {m[0] - cam.centre[0], m[1] - cam.centre[1], m[2] - cam.centre[2]};
  const float dist = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  float dir[3] = {0.f, 0.f, 1.f};
  if (dist > 0) dir[0] = d[0] / dist, dir[1] = d[1] / dist, dir[2] = d[2] / dist;
  const int bits = int(cn.w);
  float gcol[3];
  for (int ch = 0; ch < 3; ++ch) gcol[ch] = (bits >> ch & 1) ? 0.f : gs[6 + ch];
  float b[16];
  sh_basis(deg, dir[0], dir[1], dir[2], b);
  for (int k = 0; k < K; ++k)
    for (int ch = 0; ch < 3; ++ch) gsh[3 * k + ch] = b[k] * gcol[ch];
  if (deg > 0 && dist > 0) {
    float bx[16], by[16], bz[16];
    sh_basis_grad(deg, dir[0], dir[1], dir[2], bx, by, bz);
    const float* co = sh + size_t(i) * K * 3;
    float gd[3] = {0, 0, 0};
    for (int k = 1; k < K; ++k) {
      const float w = co[3 * k] * gcol[0] + co[3 * k + 1] * gcol[1] + co[3 * k + 2] * gcol[2];
      gd[0] += w * bx[k], gd[1] += w * by[k], gd[2] += w * bz[k];
    }
    const float dd = dir[0] * gd[0] + dir[1] * gd[1] + dir[2] * gd[2];
    for (int r = 0; r < 3; ++r) gmean[r] += (gd[r] - dir[r] * dd) / dist;
  }
  // Conic -> 2D covariance: dS2 = -Q G Q, G = [[da, db / 2], [db / 2, dc]].
  const float Qa = cn.x, Qb = cn.y, Qc = cn.z;
  const float Ga = gs[2], Gb = 0.5f * gs[3], Gc = gs[4];
  // Q G = [[Qa Ga + Qb Gb, Qa Gb + Qb Gc], [Qb Ga + Qc Gb, Qb Gb + Qc Gc]]
  const float P00 = Qa * Ga + Qb * Gb, P01 = Qa * Gb + Qb * Gc;
  const float P10 = Qb * Ga + Qc * Gb, P11 = Qb * Gb + Qc * Gc;
  float dS2[4];
  dS2[0] = -(P00 * Qa + P01 * Qb);
  dS2[1] = -(P00 * Qb + P01 * Qc);
  dS2[2] = -(P10 * Qa + P11 * Qb);
  dS2[3] = -(P10 * Qb + P11 * Qc);
  float p[3];
  camera_point(cam, m, p);
  const float x = p[0], y = p[1], z = p[2];
  float gp[3] = {0, 0, 0};
  // 2D mean.
  gp[0] += gs[0] * cam.fx / z;
  gp[1] += gs[1] * cam.fy / z;
  gp[2] += -gs[0] * cam.fx * x / (z * z) - gs[1] * cam.fy * y / (z * z);
  // 2D covariance -> 3D covariance and the point through J.
  M3 S;
  cov3d(&quats[4 * i], &log_scales[3 * i], S);
  float Tm[6], ux, uy;
  ewa_T(cam, p, Tm, ux, uy);
  // dS3 = T^T dS2 T
  M3 dS3;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      float s = 0;
      for (int a = 0; a < 2; ++a)
        for (int bb = 0; bb < 2; ++bb) s += Tm[3 * a + r] * dS2[2 * a + bb] * Tm[3 * bb + c];
      dS3(r, c) = s;
    }
  // GTm = 2 dS2 T S3 (2 x 3); GJ = GTm W^T
  float TS[6];
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c)
      TS[3 * r + c] = Tm[3 * r] * S(0, c) + Tm[3 * r + 1] * S(1, c) + Tm[3 * r + 2] * S(2, c);
  float GT[6];
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c)
      GT[3 * r + c] = 2 * (dS2[2 * r] * TS[c] + dS2[2 * r + 1] * TS[3 + c]);
  float GJ[6];
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c)
      GJ[3 * r + c] = GT[3 * r] * cam.R[3 * c] + GT[3 * r + 1] * cam.R[3 * c + 1] +
                      GT[3 * r + 2] * cam.R[3 * c + 2];
  const float z2 = z * z;
  gp[2] += -GJ[0] * cam.fx / z2 - GJ[4] * cam.fy / z2;
  gp[2] += GJ[2] * cam.fx * ux / z2 + GJ[5] * cam.fy * uy / z2;
  const float rx = x / z, ry = y / z;
  if (rx > cam.lox && rx < cam.hix) {
    const float gux = -GJ[2] * cam.fx / z;
    gp[0] += gux / z;
    gp[2] -= gux * x / z2;
  }
  if (ry > cam.loy && ry < cam.hiy) {
    const float guy = -GJ[5] * cam.fy / z;
    gp[1] += guy / z;
    gp[2] -= guy * y / z2;
  }
  // Camera -> world: dm += R^T dp.
  for (int r = 0; r < 3; ++r)
    gmean[r] += cam.R[r] * gp[0] + cam.R[3 + r] * gp[1] + cam.R[6 + r] * gp[2];
  for (int r = 0; r < 3; ++r) g_means[3 * i + r] = gmean[r];
  // 3D covariance -> log-scales and the raw quaternion (projection.hpp's
  // quat_scale_to_cov3d_backward).
  const float* q = &quats[4 * i];
  const float qn = sqrtf(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  const float qw = q[0] / qn, qx = q[1] / qn, qy = q[2] / qn, qz = q[3] / qn;
  const M3 Rq = quat_matrix(qw, qx, qy, qz);
  float sc[3];
  M3 Mm;
  for (int c = 0; c < 3; ++c) {
    sc[c] = expf(log_scales[3 * i + c]);
    for (int r = 0; r < 3; ++r) Mm(r, c) = Rq(r, c) * sc[c];
  }
  M3 GM = mul(dS3, Mm);
  for (int k = 0; k < 9; ++k) GM.m[k] *= 2;
  M3 GR;
  for (int c = 0; c < 3; ++c) {
    float dotc = 0;
    for (int r = 0; r < 3; ++r) {
      GR(r, c) = GM(r, c) * sc[c];
      dotc += GM(r, c) * Rq(r, c);
    }
    g_ls[3 * i + c] = dotc * sc[c];
  }
  const float gw = 2 * (-qz * GR(0, 1) + qy * GR(0, 2) + qz * GR(1, 0) - qx * GR(1, 2) -
                        qy * GR(2, 0) + qx * GR(2, 1));
  const float gx = 2 * (qy * GR(0, 1) + qz * GR(0, 2) + qy * GR(1, 0) - 2 * qx * GR(1, 1) -
                        qw * GR(1, 2) + qz * GR(2, 0) + qw * GR(2, 1) - 2 * qx * GR(2, 2));
  const float gy = 2 * (-2 * qy * GR(0, 0) + qx * GR(0, 1) + qw * GR(0, 2) + qx * GR(1, 0) +
                        qz * GR(1, 2) - qw * GR(2, 0) + qz * GR(2, 1) - 2 * qy * GR(2, 2));
  const float gz = 2 * (-2 * qz * GR(0, 0) - qw * GR(0, 1) + qx * GR(0, 2) + qw * GR(1, 0) -
                        2 * qz * GR(1, 1) + qy * GR(1, 2) + qx * GR(2, 0) + qy * GR(2, 1));
  const float dotq = qw * gw + qx * gx + qy * gy + qz * gz;
  g_q[4 * i] = (gw - qw * dotq) / qn;
  g_q[4 * i + 1] = (gx - qx * dotq) / qn;
  g_q[4 * i + 2] = (gy - qy * dotq) / qn;
  g_q[4 * i + 3] = (gz - qz * dotq) / qn;
}

int blocks_for(size_t n, int per) {
  return int((n + per - 1) / per);
}

}  // namespace

struct RasterizerCuda::State {
  cudaStream_t stream = nullptr;
  cudaEvent_t ev[4] = {nullptr, nullptr, nullptr, nullptr};
  int N = 0, deg = 0;
  DeviceArray<float> means, log_scales, quats, logits, sh;
  DeviceArray<float> rec_xy_o, rec_conic, rec_rgb;  // 4 floats a Gaussian each
  DeviceArray<int> radii;
  DeviceArray<float> depths;
  DeviceArray<uint2> tile_rect;
  DeviceArray<uint32_t> touched, offsets;
  DeviceArray<uint64_t> keys, keys_sorted;
  DeviceArray<uint32_t> vals, vals_sorted;
  DeviceArray<uint2> ranges;
  DeviceArray<unsigned char> temp;
  DeviceArray<float> color, alpha, depth, final_T;
  DeviceArray<uint32_t> n_last;
  DeviceArray<float> dL_dcolor, dL_dalpha, gscreen;
  DeviceArray<float> g_means, g_ls, g_q, g_logit, g_sh, g_m2d;
  // Posing on the device (upload_skinned / pose): the canonical means, rotations, opacity
  // logits, skin and normals, and one frame's transforms and offsets.
  DeviceArray<float> c_means, c_quats, c_logits, skin_w, normals, tf, pose_off;
  DeviceArray<int> skin_j;
  std::vector<float> tf_host;
  PinnedStage stage;  // the per-step copies' host side
  int skin_K = 0, skin_max_joint = -1;
  bool skinned = false;
  // The last forward.
  Cam cam{};
  RasterSettings settings;
  int tiles_x = 0, tiles_y = 0;
  size_t entries = 0;
  bool have_forward = false, full_forward = false, have_backward = false;

  Records records() {
    return {reinterpret_cast<float4*>(rec_xy_o.p), reinterpret_cast<float4*>(rec_conic.p),
            reinterpret_cast<float4*>(rec_rgb.p)};
  }
  Images images() {
    const bool full = full_forward;
    return {color.p, alpha.p, settings.depth ? depth.p : nullptr, full ? final_T.p : nullptr,
            full ? n_last.p : nullptr};
  }
};

bool raster_cuda_compiled() {
  return true;
}

int raster_cuda_devices() {
  int n = 0;
  if (cudaGetDeviceCount(&n) != cudaSuccess) {
    cudaGetLastError();  // clear the error state
    return 0;
  }
  return n;
}

std::string raster_cuda_describe() {
  int n = 0;
  const cudaError_t e = cudaGetDeviceCount(&n);
  if (e != cudaSuccess) {
    cudaGetLastError();
    return std::string("no CUDA device: ") + cudaGetErrorString(e);
  }
  if (n == 0) return "no CUDA device";
  cudaDeviceProp p;
  if (cudaGetDeviceProperties(&p, 0) != cudaSuccess) return "CUDA device 0 could not be queried";
  char buf[512];
  std::snprintf(buf, sizeof buf, "%.200s, %d SMs, %.1f GiB, compute %d.%d", p.name,
                p.multiProcessorCount, double(p.totalGlobalMem) / (1024.0 * 1024 * 1024), p.major,
                p.minor);
  return buf;
}

RasterizerCuda::RasterizerCuda() : st_(std::make_unique<State>()) {
  if (raster_cuda_devices() == 0) throw Error("--device cuda: " + raster_cuda_describe());
  check(cudaSetDevice(0), "cudaSetDevice");
  check(cudaStreamCreateWithFlags(&st_->stream, cudaStreamNonBlocking), "cudaStreamCreate");
  for (auto& e : st_->ev) check(cudaEventCreate(&e), "cudaEventCreate");
}

RasterizerCuda::~RasterizerCuda() {
  if (!st_) return;
  if (st_->stream) cudaStreamSynchronize(st_->stream);
  for (auto& e : st_->ev)
    if (e) cudaEventDestroy(e);
  if (st_->stream) cudaStreamDestroy(st_->stream);
}

void RasterizerCuda::upload(const Gaussians& g) {
  const size_t N = g.size();
  if (g.sh_degree < 0 || g.sh_degree > 3)
    throw Error("CUDA rasterizer: SH degree " + std::to_string(g.sh_degree) + " (0..3 supported)");
  if (g.means.size() != 3 * N || g.log_scales.size() != 3 * N || g.quats.size() != 4 * N ||
      g.sh.size() != N * size_t(g.coeffs()) * 3)
    throw Error("CUDA rasterizer: the Gaussians' arrays have inconsistent sizes");
  if (N > size_t(INT32_MAX / 16)) throw Error("CUDA rasterizer: too many Gaussians");
  State& s = *st_;
  s.N = int(N);
  s.deg = g.sh_degree;
  upload_spans(s.stage, s.stream,
               {up(s.means, g.means), up(s.log_scales, g.log_scales), up(s.quats, g.quats),
                up(s.logits, g.opacity_logits), up(s.sh, g.sh)});
  s.have_forward = s.have_backward = false;
  s.skinned = false;
}

void RasterizerCuda::upload_skinned(const Gaussians& c, const std::vector<int>& skin_joints,
                                    const std::vector<float>& skin_weights,
                                    const std::vector<float>& normals) {
  const size_t N = c.size();
  const size_t K = N > 0 ? skin_joints.size() / N : 0;
  if (N > 0 && (K < 1 || skin_joints.size() != K * N || skin_weights.size() != K * N))
    throw Error("CUDA posing: skin joints / weights must be K per Gaussian (" +
                std::to_string(skin_joints.size()) + " joints, " +
                std::to_string(skin_weights.size()) + " weights for " + std::to_string(N) +
                " Gaussians)");
  if (!normals.empty() && normals.size() != 3 * N)
    throw Error("CUDA posing: " + std::to_string(normals.size()) + " normal values for " +
                std::to_string(N) + " Gaussians (3 each, or none)");
  int largest = -1;
  for (const int j : skin_joints) {
    if (j < 0) throw Error("CUDA posing: negative skin joint " + std::to_string(j));
    largest = std::max(largest, j);
  }
  upload(c);  // checks the arrays; scales and SH stay as they are
  State& s = *st_;
  s.c_means.upload(c.means, s.stream);
  s.c_quats.upload(c.quats, s.stream);
  s.c_logits.upload(c.opacity_logits, s.stream);
  s.skin_j.upload(skin_joints, s.stream);
  s.skin_w.upload(skin_weights, s.stream);
  s.normals.upload(normals, s.stream);
  s.skin_K = int(K);
  s.skin_max_joint = largest;
  s.skinned = true;
}

void RasterizerCuda::pose(const std::vector<Eigen::Matrix4d>& transforms, const float* pose_offsets,
                          const BackfaceCull* cull) {
  State& s = *st_;
  if (!s.skinned) throw Error("CUDA posing: pose before upload_skinned");
  if (int(transforms.size()) <= s.skin_max_joint)
    throw Error("CUDA posing: skin joint " + std::to_string(s.skin_max_joint) + " out of range (" +
                std::to_string(transforms.size()) + " transforms)");
  if (cull && !(cull->threshold >= 0.f && cull->threshold <= 1.f))
    throw Error("CUDA posing: the back-face cull threshold must be in [0, 1]");
  const size_t N = size_t(s.N);
  skin_transforms_3x4(transforms, s.tf_host);
  s.tf.upload(s.tf_host, s.stream);
  LbsArgs a;
  if (pose_offsets && N > 0) {
    s.pose_off.resize(3 * N);
    check(cudaMemcpyAsync(s.pose_off.p, pose_offsets, 3 * N * sizeof(float), cudaMemcpyHostToDevice,
                          s.stream),
          "copy of the pose offsets");
    a.offsets = s.pose_off.p;
  }
  if (cull && s.normals.n == 3 * N && cull->threshold < 1.f) {
    a.normals = s.normals.p;
    for (int k = 0; k < 3; ++k) a.eye[k] = float(cull->eye[k]);
    a.threshold = cull->threshold;
  }
  a.N = s.N;
  a.K = s.skin_K;
  a.means = s.c_means.p, a.quats = s.c_quats.p, a.logits = s.c_logits.p;
  a.joints = s.skin_j.p, a.weights = s.skin_w.p, a.transforms = s.tf.p;
  a.culled_logit = kCulledOpacityLogit;
  a.out_means = s.means.p, a.out_quats = s.quats.p, a.out_logits = s.logits.p;
  check(launch_lbs(a, s.stream), "posing");
  s.have_forward = s.have_backward = false;
}

void RasterizerCuda::download_gaussians(Gaussians& out) const {
  State& s = *st_;
  out.sh_degree = s.deg;
  s.means.download(out.means, s.stream);
  s.log_scales.download(out.log_scales, s.stream);
  s.quats.download(out.quats, s.stream);
  s.logits.download(out.opacity_logits, s.stream);
  s.sh.download(out.sh, s.stream);
  check(cudaStreamSynchronize(s.stream), "download of the Gaussians");
}

void RasterizerCuda::forward(const Camera& camera, const RasterSettings& settings) {
  State& s = *st_;
  if (camera.width <= 0 || camera.height <= 0)
    throw Error("CUDA rasterizer: the camera has no pixels");
  const int N = s.N;
  s.cam = make_cam(camera);
  s.settings = settings;
  s.full_forward = !settings.image_only;
  s.tiles_x = (camera.width + kTile - 1) / kTile;
  s.tiles_y = (camera.height + kTile - 1) / kTile;
  const int ntiles = s.tiles_x * s.tiles_y;
  const size_t npix = size_t(camera.width) * camera.height;
  s.rec_xy_o.resize(4 * size_t(N));
  s.rec_conic.resize(4 * size_t(N));
  s.rec_rgb.resize(4 * size_t(N));
  s.radii.resize(N);
  s.depths.resize(N);
  s.tile_rect.resize(N);
  s.touched.resize(N);
  s.offsets.resize(N);
  s.ranges.resize(ntiles);
  s.color.resize(3 * npix);
  s.alpha.resize(npix);
  if (settings.depth) s.depth.resize(npix);
  if (s.full_forward) {
    s.final_T.resize(npix);
    s.n_last.resize(npix);
  }
  cudaStream_t st = s.stream;
  check(cudaEventRecord(s.ev[0], st), "cudaEventRecord");
  const int tpb = 256;
  if (N > 0)
    project_kernel<<<blocks_for(N, tpb), tpb, 0, st>>>(
        N, s.deg, s.means.p, s.log_scales.p, s.quats.p, s.logits.p, s.sh.p, s.cam,
        settings.near_plane, settings.low_pass, s.records(), s.radii.p, s.depths.p, s.tile_rect.p,
        s.touched.p);
  check(cudaGetLastError(), "projection");
  // Each Gaussian's first entry, and the total.
  size_t temp_bytes = 0;
  if (N > 0) {
    check(cub::DeviceScan::ExclusiveSum(nullptr, temp_bytes, s.touched.p, s.offsets.p, N, st),
          "scan size");
    s.temp.resize(temp_bytes);
    check(cub::DeviceScan::ExclusiveSum(s.temp.p, temp_bytes, s.touched.p, s.offsets.p, N, st),
          "scan");
  }
  uint32_t last_off = 0, last_cnt = 0;
  if (N > 0) {
    check(cudaMemcpyAsync(&last_off, s.offsets.p + N - 1, 4, cudaMemcpyDeviceToHost, st), "copy");
    check(cudaMemcpyAsync(&last_cnt, s.touched.p + N - 1, 4, cudaMemcpyDeviceToHost, st), "copy");
    check(cudaStreamSynchronize(st), "projection and scan");
  }
  const size_t M = size_t(last_off) + last_cnt;
  s.entries = M;
  check(cudaMemsetAsync(s.ranges.p, 0, sizeof(uint2) * ntiles, st), "memset");
  s.keys.resize(M);
  s.keys_sorted.resize(M);
  s.vals.resize(M);
  s.vals_sorted.resize(M);
  if (M > 0) {
    duplicate_kernel<<<blocks_for(N, tpb), tpb, 0, st>>>(N, s.tile_rect.p, s.touched.p, s.offsets.p,
                                                         s.depths.p, s.tiles_x, s.keys.p, s.vals.p);
    check(cudaGetLastError(), "duplication");
    int tile_bits = 1;
    while ((1 << tile_bits) < ntiles) ++tile_bits;
    size_t sort_bytes = 0;
    check(cub::DeviceRadixSort::SortPairs(nullptr, sort_bytes, s.keys.p, s.keys_sorted.p, s.vals.p,
                                          s.vals_sorted.p, M, 0, 32 + tile_bits, st),
          "sort size");
    s.temp.resize(std::max(sort_bytes, temp_bytes));
    check(cub::DeviceRadixSort::SortPairs(s.temp.p, sort_bytes, s.keys.p, s.keys_sorted.p, s.vals.p,
                                          s.vals_sorted.p, M, 0, 32 + tile_bits, st),
          "sort");
    ranges_kernel<<<blocks_for(M, tpb), tpb, 0, st>>>(uint32_t(M), s.keys_sorted.p, s.ranges.p);
    check(cudaGetLastError(), "tile ranges");
  }
  const float3 bg =
      make_float3(settings.background[0], settings.background[1], settings.background[2]);
  composite_kernel<<<ntiles, kBlock, 0, st>>>(camera.width, camera.height, s.tiles_x, s.ranges.p,
                                              s.vals_sorted.p, s.records(), bg, s.images());
  check(cudaGetLastError(), "compositing");
  check(cudaEventRecord(s.ev[1], st), "cudaEventRecord");
  s.have_forward = true;
  s.have_backward = false;
}

void RasterizerCuda::download(RasterResult& out, bool per_gaussian) const {
  State& s = *st_;
  if (!s.have_forward) throw Error("CUDA rasterizer: download before any forward");
  const int W = s.cam.W, H = s.cam.H;
  out.image_only = !s.full_forward;
  // The images' buffers are reused when their size is right (playback's frames): every value
  // is overwritten by the copy.
  auto shape = [&](Image& im, int channels) {
    if (im.width != W || im.height != H || im.channels != channels) im = Image(W, H, channels);
  };
  shape(out.color, 3);
  shape(out.alpha, 1);
  if (s.settings.depth)
    shape(out.depth, 1);
  else
    out.depth = Image();
  if (!per_gaussian) out.radii.clear(), out.depths.clear();
  download_spans(s.stage, s.stream,
                 {down(s.color, out.color.data), down(s.alpha, out.alpha.data),
                  s.settings.depth ? down(s.depth, out.depth.data) : Span{nullptr, nullptr, 0},
                  per_gaussian ? down(s.radii, out.radii) : Span{nullptr, nullptr, 0},
                  per_gaussian ? down(s.depths, out.depths) : Span{nullptr, nullptr, 0}});
}

void RasterizerCuda::backward(const Image& dL_dcolor, const Image& dL_dalpha) {
  State& s = *st_;
  if (!s.have_forward || !s.full_forward)
    throw Error("CUDA rasterizer: the backward needs a full (not image-only) forward first");
  const int W = s.cam.W, H = s.cam.H;
  if (dL_dcolor.width != W || dL_dcolor.height != H || dL_dcolor.channels != 3)
    throw Error("CUDA rasterizer: dL/dcolor must be " + std::to_string(W) + " x " +
                std::to_string(H) + " x 3");
  const bool with_alpha = !dL_dalpha.empty();
  if (with_alpha && (dL_dalpha.width != W || dL_dalpha.height != H || dL_dalpha.channels != 1))
    throw Error("CUDA rasterizer: dL/dalpha must be empty or " + std::to_string(W) + " x " +
                std::to_string(H) + " x 1");
  cudaStream_t st = s.stream;
  upload_spans(s.stage, st,
               {up(s.dL_dcolor, dL_dcolor.data),
                with_alpha ? up(s.dL_dalpha, dL_dalpha.data) : Span{nullptr, nullptr, 0}});
  const int N = s.N;
  const int K = (s.deg + 1) * (s.deg + 1);
  s.gscreen.resize(size_t(kNG) * N);
  s.g_means.resize(3 * size_t(N));
  s.g_ls.resize(3 * size_t(N));
  s.g_q.resize(4 * size_t(N));
  s.g_logit.resize(N);
  s.g_sh.resize(size_t(N) * K * 3);
  s.g_m2d.resize(2 * size_t(N));
  check(cudaEventRecord(s.ev[2], st), "cudaEventRecord");
  check(cudaMemsetAsync(s.gscreen.p, 0, sizeof(float) * kNG * size_t(N), st), "memset");
  const float3 bg =
      make_float3(s.settings.background[0], s.settings.background[1], s.settings.background[2]);
  const int ntiles = s.tiles_x * s.tiles_y;
  backward_kernel<<<ntiles, kBlock, 0, st>>>(W, H, s.tiles_x, s.ranges.p, s.vals_sorted.p,
                                             s.records(), bg, s.images(), s.dL_dcolor.p,
                                             with_alpha ? s.dL_dalpha.p : nullptr, s.gscreen.p);
  check(cudaGetLastError(), "backward compositing");
  if (N > 0)
    chain_rule_kernel<<<blocks_for(N, 128), 128, 0, st>>>(
        N, s.deg, s.means.p, s.log_scales.p, s.quats.p, s.sh.p, s.cam, s.radii.p, s.records(),
        s.gscreen.p, s.g_means.p, s.g_ls.p, s.g_q.p, s.g_logit.p, s.g_sh.p, s.g_m2d.p);
  check(cudaGetLastError(), "chain rule");
  check(cudaEventRecord(s.ev[3], st), "cudaEventRecord");
  s.have_backward = true;
}

void RasterizerCuda::download_grads(RasterGrads& gr) const {
  State& s = *st_;
  if (!s.have_backward) throw Error("CUDA rasterizer: download_grads before any backward");
  download_spans(
      s.stage, s.stream,
      {down(s.g_means, gr.means), down(s.g_ls, gr.log_scales), down(s.g_q, gr.quats),
       down(s.g_logit, gr.opacity_logits), down(s.g_sh, gr.sh), down(s.g_m2d, gr.means2d)});
}

void RasterizerCuda::synchronize() const {
  check(cudaStreamSynchronize(st_->stream), "synchronize");
}

float RasterizerCuda::last_forward_ms() const {
  float ms = 0;
  if (st_->have_forward) check(cudaEventElapsedTime(&ms, st_->ev[0], st_->ev[1]), "event time");
  return ms;
}

float RasterizerCuda::last_backward_ms() const {
  float ms = 0;
  if (st_->have_backward) check(cudaEventElapsedTime(&ms, st_->ev[2], st_->ev[3]), "event time");
  return ms;
}

size_t RasterizerCuda::last_tile_entries() const {
  return st_->entries;
}

}  // namespace ks::cuda
