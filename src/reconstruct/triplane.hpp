#pragma once
// A learnable triplane (EG3D / SIAvatar): three axis-aligned feature planes XY, XZ, YZ over the
// canonical bounding box, each res x res with C channels. A point's feature is the CONCATENATION
// of its bilinear lookups in the three planes (XY, XZ, YZ order): 3C values (SIAvatar, eq. F_tri).
// Points outside the box are clamped to its border. Forward/backward for batches of points;
// gradients w.r.t. the planes only (anchors are fixed; positions move through decoded offsets).
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
// Accumulates (adds) dL/dplanes into dplanes (size tp.size()). Race-free and the same for any
// thread count: points are binned by texel row into stripes of each plane, and threads take
// every other stripe in two passes.
template <typename T>
void triplane_backward(const TriplaneT<T>& tp, const T* xs, const T* ys, const T* zs, int n,
                       const T* dfeats, T* dplanes);

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
