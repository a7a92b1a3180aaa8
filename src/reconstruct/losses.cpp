#include "reconstruct/losses.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <type_traits>
#include <vector>

#include "core/error.hpp"
#include "core/parallel_sum.hpp"

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

// One row of each pass of the separable blur below, tap-major (for each tap, a contiguous update of
// the row) so that they vectorise; each output sums its taps in index order, as multiplies and
// adds (no fused multiply-add), so every instruction set gives the same bits.
template <typename T>
[[gnu::always_inline]] inline void blur_row_h(const T* r, T* o, int w, const T* g) {
  for (int x = 0; x < w; ++x) o[x] = 0;
  for (int k = 0; k < kWin; ++k) {
    // Output x reads r[x + k - kHalf]: valid for x in [kHalf - k, w + kHalf - k).
    const int xa = std::max(0, kHalf - k), xb = std::min(w, w + kHalf - k);
    const T gk = g[k];
    const T* rk = r + (k - kHalf);
    for (int x = xa; x < xb; ++x) o[x] += gk * rk[x];
  }
}

template <typename T>
[[gnu::always_inline]] inline void blur_row_v(const T* tmp, T* o, int w, int h, int y, const T* g) {
  const int k0 = std::max(0, kHalf - y), k1 = std::min(kWin, h - y + kHalf);
  for (int x = 0; x < w; ++x) o[x] = 0;
  for (int k = k0; k < k1; ++k) {
    const T gk = g[k];
    const T* r = tmp + size_t(y + k - kHalf) * w;
    for (int x = 0; x < w; ++x) o[x] += gk * r[x];
  }
}

// The float rows again, compiled for AVX2 (chosen at run time when the CPU has it).
__attribute__((target("avx2"))) void blur_row_h_avx2(const float* r, float* o, int w,
                                                     const float* g) {
  blur_row_h(r, o, w, g);
}
__attribute__((target("avx2"))) void blur_row_v_avx2(const float* tmp, float* o, int w, int h,
                                                     int y, const float* g) {
  blur_row_v(tmp, o, w, h, y, g);
}

template <typename T>
bool blur_use_avx2() {
  if constexpr (std::is_same_v<T, float>) {
    static const bool ok = __builtin_cpu_supports("avx2");
    return ok;
  }
  return false;
}

// The separable Gaussian blur (zero padding) a row at a time: h blurs a row of a planar image
// (w wide), v makes row y of the blur from the h-blurred image (w x h). The operator is symmetric
// (the transpose of zero-padded correlation with a symmetric kernel is itself).
template <typename T>
struct Blur {
  const std::array<T, kWin>& g = window();
  bool avx2 = blur_use_avx2<T>();
  static const std::array<T, kWin>& window() {
    static const std::array<T, kWin> w = gaussian_window<T>();
    return w;
  }
  void h(const T* in, T* out, int w) const {
    if constexpr (std::is_same_v<T, float>)
      if (avx2) return blur_row_h_avx2(in, out, w, g.data());
    blur_row_h(in, out, w, g.data());
  }
  void v(const T* hmap, T* out, int w, int hgt, int y) const {
    if constexpr (std::is_same_v<T, float>)
      if (avx2) return blur_row_v_avx2(hmap, out, w, hgt, y, g.data());
    blur_row_v(hmap, out, w, hgt, y, g.data());
  }
};

// The smallest rectangle holding every pixel where x and y differ in any channel, grown by
// `margin` and clipped to the image; false when the images are equal.
template <typename T>
bool differing_rect(const T* x, const T* y, int w, int h, int ch, int margin, int* rx0, int* rx1,
                    int* ry0, int* ry1) {
  // Each row's first and last differing element (-1: none), rows over the threads.
  std::vector<int> firsts(static_cast<size_t>(h)), lasts(static_cast<size_t>(h));
#pragma omp parallel for schedule(static) if (size_t(w) * h * ch > 65536)
  for (int yy = 0; yy < h; ++yy) {
    const T* a = x + size_t(yy) * w * ch;
    const T* b = y + size_t(yy) * w * ch;
    int first = -1, last = -1;
    for (int i = 0; i < w * ch; ++i)
      if (a[i] != b[i]) {
        first = i;
        break;
      }
    if (first >= 0)
      for (int i = w * ch - 1; i >= first; --i)
        if (a[i] != b[i]) {
          last = i;
          break;
        }
    firsts[size_t(yy)] = first, lasts[size_t(yy)] = last;
  }
  int x0 = w, x1 = -1, y0 = h, y1 = -1;
  for (int yy = 0; yy < h; ++yy) {
    if (firsts[size_t(yy)] < 0) continue;
    x0 = std::min(x0, firsts[size_t(yy)] / ch);
    x1 = std::max(x1, lasts[size_t(yy)] / ch);
    y0 = std::min(y0, yy);
    y1 = yy;
  }
  if (y1 < 0) return false;
  *rx0 = std::max(0, x0 - margin);
  *rx1 = std::min(w - 1, x1 + margin);
  *ry0 = std::max(0, y0 - margin);
  *ry1 = std::min(h - 1, y1 + margin);
  return true;
}

// Scratch for ssim (kept between calls: no allocation or page faults per step): the crop's x
// and y, the h-blurred maps of x, y, x^2, y^2, xy and of the gradient maps a, b, c; and, per
// thread, rows.
template <typename T>
struct SsimScratch {
  std::vector<T> X, Y, hX, hY, hXX, hYY, hXY, ha, hb, hc;
  void resize(size_t n) {
    for (auto* v : {&X, &Y, &hX, &hY, &hXX, &hYY, &hXY, &ha, &hb, &hc}) v->resize(n);
  }
};
template <typename T>
struct SsimRows {
  std::vector<T> r;  // 8 rows of the crop's width
  T* row(int i, int w) {
    if (r.size() < size_t(8) * size_t(w)) r.resize(size_t(8) * size_t(w));
    return r.data() + size_t(i) * size_t(w);
  }
};

constexpr double kC1 = 0.01 * 0.01;
constexpr double kC2 = 0.03 * 0.03;

}  // namespace

// Where x and y agree over a whole window, SSIM is exactly 1 there and its gradient vanishes (x = y
// is its maximum). So only the rectangle of differing pixels grown by two half-windows is computed
// (one half-window for the values, one more for the gradient's reach); its zero padding at an
// inner edge pads x and y alike, which keeps every window there equal. The pixels outside count 1.
template <typename T>
T ssim(const T* x, const T* y, int w, int h, int ch, std::vector<T>* map, T grad_scale, T* dx) {
  const size_t P = size_t(w) * h;
  if (map) map->assign(P * ch, T(1));
  int rx0, rx1, ry0, ry1;
  if (!differing_rect(x, y, w, h, ch, 2 * kHalf, &rx0, &rx1, &ry0, &ry1)) return T(1);
  const int cw = rx1 - rx0 + 1, chh = ry1 - ry0 + 1;
  const size_t Q = size_t(cw) * chh;
  thread_local SsimScratch<T> S;
  S.resize(Q);
  T *X = S.X.data(), *Y = S.Y.data(), *hX = S.hX.data(), *hY = S.hY.data();
  T *hXX = S.hXX.data(), *hYY = S.hYY.data(), *hXY = S.hXY.data();
  T *ha = S.ha.data(), *hb = S.hb.data(), *hc = S.hc.data();
  const Blur<T> blur;
  double total = double(P - Q) * ch;
  const T C1 = T(kC1), C2 = T(kC2);
  const double norm = 1.0 / double(P * ch);
  const bool par = Q > 16384;
  const bool grad = grad_scale != T(0);
  std::vector<double> row_sum(static_cast<size_t>(chh));
  // Per channel, three passes over the crop's rows (each over the threads): (1) x, y and their
  // products, h-blurred; (2) each row's v-blur, its SSIM and, for the gradient, the maps a, b, c,
  // h-blurred; (3) their v-blur, into dx. Each value is computed as a whole-image blur would
  // compute it: the same operations in the same order.
  for (int k = 0; k < ch; ++k) {
#pragma omp parallel for schedule(static) if (par)
    for (int r = 0; r < chh; ++r) {
      thread_local SsimRows<T> rows;
      const T* xr = x + ((size_t(ry0) + r) * w + rx0) * ch + k;
      const T* yr = y + ((size_t(ry0) + r) * w + rx0) * ch + k;
      const size_t q0 = size_t(r) * cw;
      T *xx = rows.row(0, cw), *yy = rows.row(1, cw), *xy = rows.row(2, cw);
      for (int i = 0; i < cw; ++i) {
        const T xv = xr[size_t(i) * ch], yv = yr[size_t(i) * ch];
        X[q0 + i] = xv;
        Y[q0 + i] = yv;
        xx[i] = xv * xv;
        yy[i] = yv * yv;
        xy[i] = xv * yv;
      }
      blur.h(X + q0, hX + q0, cw);
      blur.h(Y + q0, hY + q0, cw);
      blur.h(xx, hXX + q0, cw);
      blur.h(yy, hYY + q0, cw);
      blur.h(xy, hXY + q0, cw);
    }
    // Per row, then the rows' sums in order: the same total for any thread count.
#pragma omp parallel for schedule(static) if (par)
    for (int r = 0; r < chh; ++r) {
      thread_local SsimRows<T> rows;
      T *mx = rows.row(0, cw), *my = rows.row(1, cw), *sxx = rows.row(2, cw);
      T *syy = rows.row(3, cw), *sxy = rows.row(4, cw), *a = rows.row(5, cw);
      T *b = rows.row(6, cw), *c = rows.row(7, cw);
      blur.v(hX, mx, cw, chh, r);
      blur.v(hY, my, cw, chh, r);
      blur.v(hXX, sxx, cw, chh, r);
      blur.v(hYY, syy, cw, chh, r);
      blur.v(hXY, sxy, cw, chh, r);
      const T gs = T(double(grad_scale) * norm);
      double sum = 0;
      for (int i = 0; i < cw; ++i) {
        const T mu1 = mx[i], mu2 = my[i];
        const T s11 = sxx[i] - mu1 * mu1, s22 = syy[i] - mu2 * mu2, s12 = sxy[i] - mu1 * mu2;
        const T A1 = 2 * mu1 * mu2 + C1, A2 = 2 * s12 + C2;
        const T B1 = mu1 * mu1 + mu2 * mu2 + C1, B2 = s11 + s22 + C2;
        const T s = (A1 * A2) / (B1 * B2);
        sum += double(s);
        if (map) (*map)[((size_t(ry0) + r) * w + rx0 + size_t(i)) * ch + k] = s;
        if (grad) {
          // d s / d mu1, d s / d s11 (sigma_x^2), d s / d s12; scaled by grad_scale / count.
          const T d_mu1 = (2 * mu2 * A2) / (B1 * B2) - s * (2 * mu1) / B1;
          const T d_s11 = -s / B2;
          const T d_s12 = 2 * A1 / (B1 * B2);
          // s11 = E[x^2] - mu1^2, s12 = E[xy] - mu1 mu2: back to the blurred maps.
          a[i] = gs * (d_mu1 - 2 * mu1 * d_s11 - mu2 * d_s12);  // d/d mx
          b[i] = gs * d_s11;                                    // d/d E[x^2]
          c[i] = gs * d_s12;                                    // d/d E[xy]
        }
      }
      row_sum[size_t(r)] = sum;
      if (grad) {
        const size_t q0 = size_t(r) * cw;
        blur.h(a, ha + q0, cw);
        blur.h(b, hb + q0, cw);
        blur.h(c, hc + q0, cw);
      }
    }
    for (double v : row_sum) total += v;
    if (grad) {
#pragma omp parallel for schedule(static) if (par)
      for (int r = 0; r < chh; ++r) {
        thread_local SsimRows<T> rows;
        T *ba = rows.row(0, cw), *bb = rows.row(1, cw), *bc = rows.row(2, cw);
        blur.v(ha, ba, cw, chh, r);
        blur.v(hb, bb, cw, chh, r);
        blur.v(hc, bc, cw, chh, r);
        T* dr = dx + ((size_t(ry0) + r) * w + rx0) * ch + k;
        const size_t q0 = size_t(r) * cw;
        for (int i = 0; i < cw; ++i)
          dr[size_t(i) * ch] += ba[i] + 2 * X[q0 + i] * bb[i] + Y[q0 + i] * bc[i];
      }
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
  const T g = T(double(scale) / double(n));
  const double s = chunked_sum(n, [&](size_t b, size_t e) {
    double part = 0;
    for (size_t i = b; i < e; ++i) {
      const T d = x[i] - y[i];
      part += std::abs(double(d));
      if (dx) dx[i] += d > 0 ? g : (d < 0 ? -g : T(0));
    }
    return part;
  });
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
  L.in_offsets.assign(n + 1, 0);
  for (int u : L.neighbours) ++L.in_offsets[u + 1];
  for (int v = 0; v < n; ++v) L.in_offsets[v + 1] += L.in_offsets[v];
  L.in_from.resize(L.neighbours.size());
  std::vector<int> fill(L.in_offsets.begin(), L.in_offsets.end() - 1);
  for (int v = 0; v < n; ++v)
    for (int j = L.offsets[v]; j < L.offsets[v + 1]; ++j) L.in_from[fill[L.neighbours[j]]++] = v;
  return L;
}

namespace {

// The Laplacian's residual pass over vertices [v0, v1): for each vertex with neighbours its
// gradient term own = g s_v (a_v - mean N(v)) and share = own / |N(v)| (what each neighbour
// loses), when own != nullptr; returns the chunk's sum of s_v |a_v - mean N(v)|^2. D: the
// channel count when fixed at compile time (the trainer's 3), else 0 and `dim` at run time; a
// channel's neighbour sum runs over the neighbours in order either way.
template <int D, typename T>
double laplacian_residuals(const Laplacian& lap, const T* a, int dim, T g, size_t v0, size_t v1,
                           T* own, T* share) {
  if constexpr (D > 0) dim = D;
  double part = 0;
  std::vector<T> mdyn(D > 0 ? 0 : static_cast<size_t>(dim));
  T mfix[D > 0 ? D : 1];
  T* m = D > 0 ? mfix : mdyn.data();
  for (size_t v = v0; v < v1; ++v) {
    const int b = lap.offsets[v], e = lap.offsets[v + 1];
    if (b == e) continue;
    const T inv = T(1) / T(e - b);
    const T sv = g * T(lap.strength[v]);
    for (int k = 0; k < dim; ++k) m[k] = T(0);
    for (int j = b; j < e; ++j) {
      const T* an = a + size_t(lap.neighbours[j]) * dim;
      for (int k = 0; k < dim; ++k) m[k] += an[k];
    }
    double sq = 0;
    for (int k = 0; k < dim; ++k) {
      const T d = a[v * dim + k] - m[k] * inv;
      sq += double(d) * double(d);
      if (own) {
        own[v * dim + k] = sv * d;
        share[v * dim + k] = own[v * dim + k] * inv;
      }
    }
    part += lap.strength[v] * sq;
  }
  return part;
}

// The gradient of vertex u gathered over the transposed lists: the own term and the shares in
// the order the serial scatter adds them (by increasing source vertex, the own term first among
// equals), so the result is the scatter's bit for bit.
template <int D, typename T>
void laplacian_gather(const Laplacian& lap, int u, int dim, const T* own, const T* share, T* da) {
  if constexpr (D > 0) {
    dim = D;
    const int b = lap.in_offsets[u], e = lap.in_offsets[u + 1];
    bool own_done = lap.offsets[u + 1] == lap.offsets[u];
    T acc[D];
    for (int k = 0; k < D; ++k) acc[k] = da[size_t(u) * D + k];
    for (int j = b; j < e; ++j) {
      const int v = lap.in_from[j];
      if (!own_done && v >= u) {
        for (int k = 0; k < D; ++k) acc[k] += own[size_t(u) * D + k];
        own_done = true;
      }
      for (int k = 0; k < D; ++k) acc[k] -= share[size_t(v) * D + k];
    }
    if (!own_done)
      for (int k = 0; k < D; ++k) acc[k] += own[size_t(u) * D + k];
    for (int k = 0; k < D; ++k) da[size_t(u) * D + k] = acc[k];
  } else {
    for (int k = 0; k < dim; ++k) {
      const int b = lap.in_offsets[u], e = lap.in_offsets[u + 1];
      bool own_done = lap.offsets[u + 1] == lap.offsets[u];
      T acc = da[size_t(u) * dim + k];
      for (int j = b; j < e; ++j) {
        const int v = lap.in_from[j];
        if (!own_done && v >= u) {
          acc += own[size_t(u) * dim + k];
          own_done = true;
        }
        acc -= share[size_t(v) * dim + k];
      }
      if (!own_done) acc += own[size_t(u) * dim + k];
      da[size_t(u) * dim + k] = acc;
    }
  }
}

template <int D, typename T>
T laplacian_loss_impl(const Laplacian& lap, const T* a, int dim, T scale, T* da) {
  const int n = lap.num_vertices();
  const double inv_n = 1.0 / n;
  const T g = T(2.0 * double(scale) * inv_n);
  // Residuals first, in parallel (chunks summed in order: the same value for any thread count).
  static thread_local std::vector<T> scratch;  // caller thread's, used by the workers below
  std::vector<T>& sc = scratch;
  sc.resize(da ? 2 * size_t(n) * dim : 0);
  T* own = da ? sc.data() : nullptr;
  T* share = da ? sc.data() + size_t(n) * dim : nullptr;
  const double total = chunked_sum(
      size_t(n),
      [&](size_t v0, size_t v1) {
        return laplacian_residuals<D>(lap, a, dim, g, v0, v1, own, share);
      },
      4096);
  if (da && lap.in_offsets.size() == size_t(n) + 1) {
#pragma omp parallel for schedule(static) if (n > 4096)
    for (int u = 0; u < n; ++u) laplacian_gather<D>(lap, u, dim, own, share, da);
  } else if (da) {
    // Scattered (lists built by hand, without the transposed ones): serial, neighbours overlap.
    for (int v = 0; v < n; ++v) {
      const int b = lap.offsets[v], e = lap.offsets[v + 1];
      if (b == e) continue;
      for (int k = 0; k < dim; ++k) {
        da[size_t(v) * dim + k] += own[size_t(v) * dim + k];
        for (int j = b; j < e; ++j)
          da[size_t(lap.neighbours[j]) * dim + k] -= share[size_t(v) * dim + k];
      }
    }
  }
  return T(total * inv_n);
}

}  // namespace

template <typename T>
T laplacian_loss(const Laplacian& lap, const T* a, int dim, T scale, T* da) {
  if (lap.num_vertices() == 0 || lap.neighbours.empty()) return T(0);
  return dim == 3 ? laplacian_loss_impl<3>(lap, a, dim, scale, da)
                  : laplacian_loss_impl<0>(lap, a, dim, scale, da);
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
