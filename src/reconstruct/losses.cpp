#include "reconstruct/losses.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "core/error.hpp"

namespace ks {

namespace {

constexpr int kWin = 11;
constexpr int kHalf = 5;

template <typename T>
std::array<T, kWin> gaussian_window() {
  std::array<T, kWin> g;
  double s = 0;
  for (int i = 0; i < kWin; ++i) {
    const double d = i - kHalf;
    g[i] = T(std::exp(-d * d / (2 * 1.5 * 1.5)));
    s += double(g[i]);
  }
  for (auto& v : g) v = T(double(v) / s);
  return g;
}

// Separable Gaussian blur, zero padding, on a single-channel planar image (w x h). The operator
// is symmetric (the transpose of zero-padded correlation with a symmetric kernel is itself).
template <typename T>
void blur(const T* in, T* out, T* tmp, int w, int h) {
  static const std::array<T, kWin> g = gaussian_window<T>();
#pragma omp parallel for schedule(static) if (size_t(w) * h > 16384)
  for (int y = 0; y < h; ++y) {
    const T* r = in + size_t(y) * w;
    T* o = tmp + size_t(y) * w;
    for (int x = 0; x < w; ++x) {
      T s = 0;
      const int k0 = std::max(0, kHalf - x), k1 = std::min(kWin, w - x + kHalf);
      for (int k = k0; k < k1; ++k) s += g[k] * r[x + k - kHalf];
      o[x] = s;
    }
  }
#pragma omp parallel for schedule(static) if (size_t(w) * h > 16384)
  for (int y = 0; y < h; ++y) {
    T* o = out + size_t(y) * w;
    const int k0 = std::max(0, kHalf - y), k1 = std::min(kWin, h - y + kHalf);
    for (int x = 0; x < w; ++x) o[x] = 0;
    for (int k = k0; k < k1; ++k) {
      const T gk = g[k];
      const T* r = tmp + size_t(y + k - kHalf) * w;
      for (int x = 0; x < w; ++x) o[x] += gk * r[x];
    }
  }
}

constexpr double kC1 = 0.01 * 0.01;
constexpr double kC2 = 0.03 * 0.03;

}  // namespace

template <typename T>
T ssim(const T* x, const T* y, int w, int h, int ch, std::vector<T>* map, T grad_scale, T* dx) {
  const size_t P = size_t(w) * h;
  std::vector<T> X(P), Y(P), XX(P), YY(P), XY(P), mx(P), my(P), sxx(P), syy(P), sxy(P), tmp(P);
  std::vector<T> a(P), b(P), c(P);
  if (map) map->assign(P * ch, T(0));
  double total = 0;
  const T C1 = T(kC1), C2 = T(kC2);
  const double norm = 1.0 / double(P * ch);
  for (int k = 0; k < ch; ++k) {
    for (size_t p = 0; p < P; ++p) {
      X[p] = x[p * ch + k];
      Y[p] = y[p * ch + k];
      XX[p] = X[p] * X[p];
      YY[p] = Y[p] * Y[p];
      XY[p] = X[p] * Y[p];
    }
    blur(X.data(), mx.data(), tmp.data(), w, h);
    blur(Y.data(), my.data(), tmp.data(), w, h);
    blur(XX.data(), sxx.data(), tmp.data(), w, h);
    blur(YY.data(), syy.data(), tmp.data(), w, h);
    blur(XY.data(), sxy.data(), tmp.data(), w, h);
    double sum = 0;
    for (size_t p = 0; p < P; ++p) {
      const T mu1 = mx[p], mu2 = my[p];
      const T s11 = sxx[p] - mu1 * mu1, s22 = syy[p] - mu2 * mu2, s12 = sxy[p] - mu1 * mu2;
      const T A1 = 2 * mu1 * mu2 + C1, A2 = 2 * s12 + C2;
      const T B1 = mu1 * mu1 + mu2 * mu2 + C1, B2 = s11 + s22 + C2;
      const T s = (A1 * A2) / (B1 * B2);
      sum += double(s);
      if (map) (*map)[p * ch + k] = s;
      if (grad_scale != T(0)) {
        // d s / d mu1, d s / d s11 (sigma_x^2), d s / d s12; scaled by grad_scale / count.
        const T gs = T(double(grad_scale) * norm);
        const T d_mu1 = (2 * mu2 * A2) / (B1 * B2) - s * (2 * mu1) / B1;
        const T d_s11 = -s / B2;
        const T d_s12 = 2 * A1 / (B1 * B2);
        // s11 = E[x^2] - mu1^2, s12 = E[xy] - mu1 mu2: back to the blurred maps.
        a[p] = gs * (d_mu1 - 2 * mu1 * d_s11 - mu2 * d_s12);  // d/d mx
        b[p] = gs * d_s11;                                    // d/d E[x^2]
        c[p] = gs * d_s12;                                    // d/d E[xy]
      }
    }
    total += sum;
    if (grad_scale != T(0)) {
      blur(a.data(), mx.data(), tmp.data(), w, h);
      blur(b.data(), sxx.data(), tmp.data(), w, h);
      blur(c.data(), sxy.data(), tmp.data(), w, h);
      for (size_t p = 0; p < P; ++p) dx[p * ch + k] += mx[p] + 2 * X[p] * sxx[p] + Y[p] * sxy[p];
    }
  }
  return T(total * norm);
}

template <typename T>
T ssim_masked(const T* x, const T* y, const float* mask, int w, int h, int ch) {
  std::vector<T> map;
  ssim<T>(x, y, w, h, ch, &map, T(0), nullptr);
  double s = 0;
  size_t n = 0;
  for (size_t p = 0; p < size_t(w) * h; ++p) {
    if (mask[p] <= 0.5f) continue;
    for (int k = 0; k < ch; ++k) s += double(map[p * ch + k]);
    n += ch;
  }
  return n ? T(s / double(n)) : T(-1);
}

template <typename T>
T l1_loss(const T* x, const T* y, size_t n, T scale, T* dx) {
  double s = 0;
  const T g = T(double(scale) / double(n));
  for (size_t i = 0; i < n; ++i) {
    const T d = x[i] - y[i];
    s += std::abs(double(d));
    if (dx) dx[i] += d > 0 ? g : (d < 0 ? -g : T(0));
  }
  return T(s / double(n));
}

LaplacianMode parse_laplacian_mode(const std::string& s) {
  if (s == "none") return LaplacianMode::kNone;
  if (s == "uniform") return LaplacianMode::kUniform;
  if (s == "semantic") return LaplacianMode::kSemantic;
  throw Error("unknown Laplacian mode '" + s + "' (expected semantic, uniform or none)");
}

const std::array<float, kNumParts>& default_part_strengths() {
  // head_neck, torso, hips, l/r upper arm, l/r lower arm, l/r hand, l/r upper leg, l/r lower leg,
  // l/r foot
  static const std::array<float, kNumParts> s = {2.0f, 0.5f, 0.5f, 1.0f, 1.0f, 1.0f, 1.0f, 2.0f,
                                                 2.0f, 0.5f, 0.5f, 0.5f, 0.5f, 1.0f, 1.0f};
  return s;
}

Laplacian build_laplacian(const std::vector<std::vector<int>>& adj, const std::vector<int>& labels,
                          LaplacianMode mode, const std::array<float, kNumParts>& part_strength) {
  Laplacian L;
  const int n = int(adj.size());
  if (mode == LaplacianMode::kSemantic && labels.size() != adj.size())
    throw Error("semantic Laplacian: " + std::to_string(labels.size()) + " labels for " +
                std::to_string(n) + " vertices");
  L.offsets.assign(n + 1, 0);
  L.strength.assign(n, 0.f);
  if (mode == LaplacianMode::kNone) return L;
  for (int v = 0; v < n; ++v) {
    for (int u : adj[v])
      if (mode == LaplacianMode::kUniform || labels[u] == labels[v]) L.neighbours.push_back(u);
    L.offsets[v + 1] = int(L.neighbours.size());
    L.strength[v] = mode == LaplacianMode::kUniform ? 1.f : part_strength[labels[v]];
  }
  return L;
}

template <typename T>
T laplacian_loss(const Laplacian& lap, const T* a, int dim, T scale, T* da) {
  const int n = lap.num_vertices();
  if (n == 0 || lap.neighbours.empty()) return T(0);
  double total = 0;
  const double inv_n = 1.0 / n;
  // Residuals first (parallel), then the scatter (serial: neighbours overlap).
  std::vector<T> r(size_t(n) * dim, T(0));
#pragma omp parallel for schedule(static) reduction(+ : total) if (n > 4096)
  for (int v = 0; v < n; ++v) {
    const int b = lap.offsets[v], e = lap.offsets[v + 1];
    if (b == e) continue;
    const T inv = T(1) / T(e - b);
    double s = 0;
    for (int k = 0; k < dim; ++k) {
      T m = 0;
      for (int j = b; j < e; ++j) m += a[size_t(lap.neighbours[j]) * dim + k];
      const T d = a[size_t(v) * dim + k] - m * inv;
      r[size_t(v) * dim + k] = d;
      s += double(d) * double(d);
    }
    total += lap.strength[v] * s;
  }
  if (da) {
    const T g = T(2.0 * double(scale) * inv_n);
    for (int v = 0; v < n; ++v) {
      const int b = lap.offsets[v], e = lap.offsets[v + 1];
      if (b == e) continue;
      const T sv = g * T(lap.strength[v]);
      const T inv = T(1) / T(e - b);
      for (int k = 0; k < dim; ++k) {
        const T gr = sv * r[size_t(v) * dim + k];
        da[size_t(v) * dim + k] += gr;
        for (int j = b; j < e; ++j) da[size_t(lap.neighbours[j]) * dim + k] -= gr * inv;
      }
    }
  }
  return T(total * inv_n);
}

template float ssim(const float*, const float*, int, int, int, std::vector<float>*, float, float*);
template double ssim(const double*, const double*, int, int, int, std::vector<double>*, double,
                     double*);
template float ssim_masked(const float*, const float*, const float*, int, int, int);
template double ssim_masked(const double*, const double*, const float*, int, int, int);
template float l1_loss(const float*, const float*, size_t, float, float*);
template double l1_loss(const double*, const double*, size_t, double, double*);
template float laplacian_loss(const Laplacian&, const float*, int, float, float*);
template double laplacian_loss(const Laplacian&, const double*, int, double, double*);

}  // namespace ks
