#pragma once
// A set of 3D Gaussians, structure of arrays, raw (pre-activation) parameters as in 3DGS:
// mean, log-scale (3), quaternion (w, x, y, z; normalised where used), opacity logit,
// colour as SH coefficients of degree 0..3 (RGB = SH . basis + 0.5, clamped at 0).
#include <cstddef>
#include <vector>

namespace ks {

inline int sh_coeff_count(int degree) {
  return (degree + 1) * (degree + 1);
}

struct Gaussians {
  int sh_degree = 0;
  std::vector<float> means;           // 3N
  std::vector<float> log_scales;      // 3N
  std::vector<float> quats;           // 4N (w, x, y, z)
  std::vector<float> opacity_logits;  // N
  std::vector<float> sh;              // N * K * 3, K = (degree+1)^2, layout [n][k][rgb]

  size_t size() const { return opacity_logits.size(); }
  int coeffs() const { return sh_coeff_count(sh_degree); }
  // Resizes every array to n Gaussians (new entries zero, quats identity).
  void resize(size_t n);
};

}  // namespace ks
