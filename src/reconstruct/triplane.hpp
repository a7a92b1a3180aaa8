#pragma once
// A learnable triplane (EG3D / SIAvatar): three axis-aligned feature planes XY, XZ, YZ over the
// canonical bounding box, each res x res with C channels. A point's feature is the CONCATENATION
// of its bilinear lookups in the three planes (XY, XZ, YZ order): 3C values (SIAvatar, eq. F_tri).
// Points outside the box are clamped to its border. Forward/backward for batches of points;
// gradients w.r.t. the planes only (anchors are fixed; positions move through decoded offsets).
// Float planes whose channel count is a multiple of 8 take AVX2+FMA loops when the CPU has them
// (triplane_kernels.hpp; KS_TRIPLANE_NO_AVX2=1 turns them off); the results then differ from the
// portable loops by float rounding only; either path gives the same results on any thread count.
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace ks {

template <typename T>
struct TriplaneT {
  int res = 128;
  int channels = 32;
  T lo[3] = {-1, -1, -1};  // bounding box (already padded)
  T hi[3] = {1, 1, 1};
  // Layout [plane][row v][column u][channel]; plane 0 = XY (u=x, v=y), 1 = XZ (u=x, v=z),
  // 2 = YZ (u=y, v=z).
  std::vector<T> planes;

  int feature_dim() const { return 3 * channels; }
  size_t plane_size() const { return size_t(res) * res * channels; }
  size_t size() const { return 3 * plane_size(); }
  // Allocates the planes with small deterministic noise (uniform in [-init_scale, init_scale]).
  void init(int res, int channels, const T box_lo[3], const T box_hi[3], uint64_t seed,
            T init_scale = T(0.1));
};

// Points in structure of arrays: xs, ys, zs (n each). feats: n x 3C, row-major (point-major).
template <typename T>
void triplane_forward(const TriplaneT<T>& tp, const T* xs, const T* ys, const T* zs, int n,
                      T* feats);
// The points binned for the backward's scatter: per plane, by the texel row of their lookup
// into horizontal stripes of rows, in index order within a stripe (so the point gradients are
// read in order; ordering by texel instead was slower, 206 against 197 ms a training step). A
// point writes rows v0 and v0 + 1, so stripes of >= 2 rows two apart never touch the same
// texel. Depends on the points and the plane size only, so a caller whose points stay fixed
// (the decoder's anchors between density edits) makes it once.
struct TriplaneBins {
  int n = 0, res = 0, stripes = 0;
  std::vector<int> start;  // 3 (stripes + 1): plane p's stripe s is order[start[p(S+1)+s], ...+1)
  std::vector<int> order;  // 3 n: plane p's points at p n
};
template <typename T>
TriplaneBins triplane_bins(const TriplaneT<T>& tp, const T* xs, const T* ys, const T* zs, int n);

// Accumulates (adds) dL/dplanes into dplanes (size tp.size()). Race-free and the same for any
// thread count: threads take every other stripe of the bins in two passes, each writing whole
// texels in the bins' order. bins: triplane_bins of these points (nullptr: made here).
template <typename T>
void triplane_backward(const TriplaneT<T>& tp, const T* xs, const T* ys, const T* zs, int n,
                       const T* dfeats, T* dplanes, const TriplaneBins* bins = nullptr);

// Marks (sets to 1) in `texels` (resized to 3 res^2 if smaller; index plane * res^2 + v * res + u)
// every texel a lookup of the points reads: the only texels triplane_backward writes for them.
template <typename T>
void triplane_mark_texels(const TriplaneT<T>& tp, const T* xs, const T* ys, const T* zs, int n,
                          std::vector<uint8_t>* texels);

// The marked texels as ranges [begin, end) of entries of `planes` (channels per texel), runs of
// neighbouring texels joined.
std::vector<std::pair<size_t, size_t>> texel_ranges(const std::vector<uint8_t>& texels,
                                                    int channels);

using Triplane = TriplaneT<float>;

}  // namespace ks
