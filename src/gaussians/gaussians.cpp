#include "gaussians/gaussians.hpp"

namespace ks {

void Gaussians::resize(size_t n) {
  const size_t old = size();
  means.resize(3 * n, 0.f);
  log_scales.resize(3 * n, 0.f);
  quats.resize(4 * n, 0.f);
  for (size_t i = old; i < n; ++i) quats[4 * i] = 1.f;
  opacity_logits.resize(n, 0.f);
  sh.resize(n * size_t(coeffs()) * 3, 0.f);
}

}  // namespace ks
