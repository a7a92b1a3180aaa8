#pragma once
// Training losses with hand-written gradients.
//   image:  w_l1 * L1 + w_ssim * (1 - SSIM)   (SSIM: 11x11 Gaussian window, sigma 1.5, zero
//           padding, C1 = 0.01^2, C2 = 0.03^2, averaged over pixels and RGB channels)
//   mask:   mean |alpha - mask| (L1)
//   offset: mean ||offset||^2
//   Laplacian (SinGS, semantic): sum_v lambda_part(v) ||a_v - mean_{u in N(v)} a_u||^2 / N over
//           anchor positions and colours; N(v) = neighbours in the same part ("semantic") or all
//           neighbours ("uniform").
// Images are interleaved (Image layout: [y][x][c]); T = float or double (the tests use double).
#include <array>
#include <string>
#include <vector>

#include "body/parts.hpp"

namespace ks {

// SSIM map (one value per pixel and channel, same layout as the input) and its mean.
// If grad_scale != 0, writes dx = grad_scale * d(mean SSIM)/dx into dx (same layout).
template <typename T>
T ssim(const T* x, const T* y, int width, int height, int channels, std::vector<T>* map,
       T grad_scale, T* dx);

// Mean of the SSIM map over pixels whose mask > 0.5 (mask: one channel); -1 if no pixel.
template <typename T>
T ssim_masked(const T* x, const T* y, const float* mask, int width, int height, int channels);

// mean |x - y| over all values; adds scale * d/dx into dx (if non-null).
template <typename T>
T l1_loss(const T* x, const T* y, size_t n, T scale, T* dx);

// Laplacian regulariser over per-vertex values (dim values per vertex, interleaved).
enum class LaplacianMode { kNone, kUniform, kSemantic };
LaplacianMode parse_laplacian_mode(const std::string& s);  // "none" | "uniform" | "semantic"

struct Laplacian {
  // CSR neighbour lists and per-vertex strength (lambda of its part, or the uniform lambda).
  std::vector<int> offsets, neighbours;
  std::vector<float> strength;
  // The lists transposed (build_laplacian fills them): the vertices v whose list holds u, for
  // each u in increasing v (with repeats), so the gradient gathers per vertex in parallel.
  // Empty: laplacian_loss scatters serially.
  std::vector<int> in_offsets, in_from;
  int num_vertices() const { return int(strength.size()); }
};

// Default per-part strengths (relative; multiplied by the loss weight): tight on the face/head and
// hands, loose on torso/hips/legs where clothes deviate from the body template. See docs.
const std::array<float, kNumParts>& default_part_strengths();

// Builds from adjacency lists (vertex_adjacency) and part labels.
Laplacian build_laplacian(const std::vector<std::vector<int>>& adjacency,
                          const std::vector<int>& labels, LaplacianMode mode,
                          const std::array<float, kNumParts>& part_strength);

// Returns sum_v s_v ||a_v - mean N(v)||^2 / N for values a (N x dim interleaved); adds
// scale * dL/da into da (if non-null). Vertices without neighbours contribute nothing.
template <typename T>
T laplacian_loss(const Laplacian& lap, const T* a, int dim, T scale, T* da);

}  // namespace ks
