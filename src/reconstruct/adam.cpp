#include "reconstruct/adam.hpp"

#include <algorithm>
#include <cmath>

#include "core/error.hpp"

namespace ks {

void Adam::add_group(const std::string& name, std::vector<float>* params,
                     const std::vector<float>* grads, float lr,
                     const std::vector<std::pair<size_t, size_t>>* active) {
  if (has_group(name)) throw Error("Adam: a group named '" + name + "' exists already");
  AdamGroup g;
  g.name = name;
  g.params = params;
  g.grads = grads;
  g.lr = lr;
  g.active = active;
  g.m.assign(params->size(), 0.f);
  g.v.assign(params->size(), 0.f);
  groups_.push_back(std::move(g));
}

bool Adam::has_group(const std::string& name) const {
  for (const AdamGroup& g : groups_)
    if (g.name == name) return true;
  return false;
}

AdamGroup& Adam::group(const std::string& name) {
  for (AdamGroup& g : groups_)
    if (g.name == name) return g;
  throw Error("Adam: no group named '" + name + "'");
}

float Adam::lr_scale() const {
  const double T = std::max(1, total_steps);
  const double t = std::min<double>(t_, T);
  const double c = 0.5 * (1.0 + std::cos(M_PI * t / T));
  return float(final_fraction + (1.0 - final_fraction) * c);
}

namespace {

// One Adam update of n entries. Raw non-aliasing pointers and a sqrt without errno (CMake:
// -fno-math-errno) let the compiler vectorise the loop (bench/train_step_bench.cpp).
void adam_update(float* __restrict pp, float* __restrict pm, float* __restrict pv,
                 const float* __restrict pd, long n, float b1, float b2, float e, float step,
                 float ibc2) {
  for (long i = 0; i < n; ++i) {
    const float m = b1 * pm[i] + (1 - b1) * pd[i];
    const float v = b2 * pv[i] + (1 - b2) * pd[i] * pd[i];
    pm[i] = m;
    pv[i] = v;
    pp[i] -= step * m / (std::sqrt(v * ibc2) + e);
  }
}

}  // namespace

void Adam::step() {
  const float scale = lr_scale();
  ++t_;
  const double bc1 = 1.0 - std::pow(double(beta1), t_);
  const double bc2 = 1.0 - std::pow(double(beta2), t_);
  for (AdamGroup& g : groups_) {
    std::vector<float>& p = *g.params;
    if (!g.grads) throw Error("Adam::step: group '" + g.name + "' has no gradient buffer");
    const std::vector<float>& d = *g.grads;
    if (d.size() != p.size() || g.m.size() != p.size())
      throw Error("Adam::step: group '" + g.name + "' has " + std::to_string(p.size()) +
                  " parameters, " + std::to_string(d.size()) + " gradients, " +
                  std::to_string(g.m.size()) + " moments");
    const float step = float(g.lr * scale / bc1);
    const float ibc2 = float(1.0 / bc2);
    if (g.active && !g.active->empty()) {
      const auto& R = *g.active;
      if (R.back().second > p.size())
        throw Error("Adam::step: group '" + g.name + "' has an active range past its end");
#pragma omp parallel for schedule(dynamic, 16)
      for (long r = 0; r < long(R.size()); ++r) {
        const size_t b = R[size_t(r)].first, e = R[size_t(r)].second;
        adam_update(p.data() + b, g.m.data() + b, g.v.data() + b, d.data() + b, long(e - b), beta1,
                    beta2, eps, step, ibc2);
      }
    } else {
      const long n = long(p.size());
      constexpr long kBlock = 1 << 14;
#pragma omp parallel for schedule(static) if (n > 65536)
      for (long b = 0; b < n; b += kBlock)
        adam_update(p.data() + b, g.m.data() + b, g.v.data() + b, d.data() + b,
                    std::min(kBlock, n - b), beta1, beta2, eps, step, ibc2);
    }
  }
}

void Adam::resize_group(const std::string& name) {
  AdamGroup& g = group(name);
  g.m.resize(g.params->size(), 0.f);
  g.v.resize(g.params->size(), 0.f);
}

void Adam::remap_group(const std::string& name, const std::vector<int>& src, int stride) {
  AdamGroup& g = group(name);
  std::vector<float> m(src.size() * stride, 0.f), v(src.size() * stride, 0.f);
  for (size_t i = 0; i < src.size(); ++i) {
    if (src[i] < 0) continue;
    if (size_t(src[i] + 1) * stride > g.m.size())
      throw Error("Adam::remap_group: source index " + std::to_string(src[i]) + " out of range");
    for (int k = 0; k < stride; ++k) {
      m[i * stride + k] = g.m[size_t(src[i]) * stride + k];
      v[i * stride + k] = g.v[size_t(src[i]) * stride + k];
    }
  }
  g.m = std::move(m);
  g.v = std::move(v);
}

void Adam::remap_group(const std::string& name,
                       const Eigen::SparseMatrix<double, Eigen::RowMajor>& S) {
  AdamGroup& g = group(name);
  if (S.cols() <= 0 || g.m.size() % size_t(S.cols()) != 0)
    throw Error("Adam::remap_group: group '" + g.name + "' has " + std::to_string(g.m.size()) +
                " moments, not a multiple of the stencil's " + std::to_string(S.cols()) +
                " columns");
  const int stride = int(g.m.size() / size_t(S.cols()));
  std::vector<int> src(size_t(S.rows()), -1);
  for (int r = 0; r < S.rows(); ++r) {
    int count = 0, col = -1;
    double value = 0;
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(S, r); it; ++it)
      ++count, col = int(it.col()), value = it.value();
    if (count == 1 && value == 1.0) src[size_t(r)] = col;
  }
  remap_group(name, src, stride);
}

}  // namespace ks
