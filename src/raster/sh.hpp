#pragma once
// Real spherical harmonics of degree 0..3 with the constants and signs of the original 3DGS code,
// and their derivatives with respect to the (unit) direction; the view-dependent colour as a
// forward / backward pair (sh_to_color). Templated for float/double.
#include <Eigen/Core>
#include <algorithm>
#include <cstdint>
#include <type_traits>

namespace ks::sh {

constexpr double kC0 = 0.28209479177387814;  // band 0: the one definition
static_assert(float(kC0) == 0.28209479177387814f, "float(kC0) is the float constant");
constexpr double kC1 = 0.4886025119029199;
constexpr double kC2[5] = {1.0925484305920792, -1.0925484305920792, 0.31539156525252005,
                           -1.0925484305920792, 0.5462742152960396};
constexpr double kC3[7] = {-0.5900435899266435, 2.890611442640554,   -0.4570457994644658,
                           0.3731763325901154,  -0.4570457994644658, 1.445305721320277,
                           -0.5900435899266435};

// A constant in T's precision; for a GCC vector type T (basis over several directions at once,
// raster/preprocess_simd.cpp) its float lanes' (a scalar times a vector is lane-wise).
template <class T>
constexpr auto sh_constant(double v) {
  if constexpr (std::is_floating_point_v<T>)
    return T(v);
  else
    return float(v);
}

// b[k] for k < (deg+1)^2 (T a float, double or float vector type).
template <class T>
inline void basis(int deg, T x, T y, T z, T* b) {
  b[0] = T{} + sh_constant<T>(kC0);
  if (deg < 1) return;
  b[1] = sh_constant<T>(-kC1) * y;
  b[2] = sh_constant<T>(kC1) * z;
  b[3] = sh_constant<T>(-kC1) * x;
  if (deg < 2) return;
  const T xx = x * x, yy = y * y, zz = z * z;
  b[4] = sh_constant<T>(kC2[0]) * x * y;
  b[5] = sh_constant<T>(kC2[1]) * y * z;
  b[6] = sh_constant<T>(kC2[2]) * (2 * zz - xx - yy);
  b[7] = sh_constant<T>(kC2[3]) * x * z;
  b[8] = sh_constant<T>(kC2[4]) * (xx - yy);
  if (deg < 3) return;
  b[9] = sh_constant<T>(kC3[0]) * y * (3 * xx - yy);
  b[10] = sh_constant<T>(kC3[1]) * x * y * z;
  b[11] = sh_constant<T>(kC3[2]) * y * (4 * zz - xx - yy);
  b[12] = sh_constant<T>(kC3[3]) * z * (2 * zz - 3 * xx - 3 * yy);
  b[13] = sh_constant<T>(kC3[4]) * x * (4 * zz - xx - yy);
  b[14] = sh_constant<T>(kC3[5]) * z * (xx - yy);
  b[15] = sh_constant<T>(kC3[6]) * x * (xx - 3 * yy);
}

// Which of basis_grad's derivatives of b[k] can be non-zero, as bits (1: x, 2: y, 4: z); the
// others are zero for every direction.
constexpr uint8_t kGradAxes[16] = {0, 2, 4, 1, 3, 6, 7, 5, 3, 3, 7, 7, 7, 7, 7, 3};

// Partial derivatives of b[k] with respect to x, y, z (treated as independent; T as for basis).
template <class T>
inline void basis_grad(int deg, T x, T y, T z, T* bx, T* by, T* bz) {
  const T zero = T{};
  bx[0] = by[0] = bz[0] = zero;
  if (deg < 1) return;
  const T c1 = zero + sh_constant<T>(kC1);
  bx[1] = zero, by[1] = -c1, bz[1] = zero;
  bx[2] = zero, by[2] = zero, bz[2] = c1;
  bx[3] = -c1, by[3] = zero, bz[3] = zero;
  if (deg < 2) return;
  const T xx = x * x, yy = y * y, zz = z * z;
  bx[4] = sh_constant<T>(kC2[0]) * y, by[4] = sh_constant<T>(kC2[0]) * x, bz[4] = zero;
  bx[5] = zero, by[5] = sh_constant<T>(kC2[1]) * z, bz[5] = sh_constant<T>(kC2[1]) * y;
  bx[6] = sh_constant<T>(-2 * kC2[2]) * x, by[6] = sh_constant<T>(-2 * kC2[2]) * y,
  bz[6] = sh_constant<T>(4 * kC2[2]) * z;
  bx[7] = sh_constant<T>(kC2[3]) * z, by[7] = zero, bz[7] = sh_constant<T>(kC2[3]) * x;
  bx[8] = sh_constant<T>(2 * kC2[4]) * x, by[8] = sh_constant<T>(-2 * kC2[4]) * y, bz[8] = zero;
  if (deg < 3) return;
  bx[9] = sh_constant<T>(kC3[0]) * 6 * x * y, by[9] = sh_constant<T>(kC3[0]) * (3 * xx - 3 * yy),
  bz[9] = zero;
  bx[10] = sh_constant<T>(kC3[1]) * y * z, by[10] = sh_constant<T>(kC3[1]) * x * z,
  bz[10] = sh_constant<T>(kC3[1]) * x * y;
  bx[11] = sh_constant<T>(kC3[2]) * (-2 * x * y),
  by[11] = sh_constant<T>(kC3[2]) * (4 * zz - xx - 3 * yy),
  bz[11] = sh_constant<T>(kC3[2]) * 8 * y * z;
  bx[12] = sh_constant<T>(kC3[3]) * (-6 * x * z), by[12] = sh_constant<T>(kC3[3]) * (-6 * y * z),
  bz[12] = sh_constant<T>(kC3[3]) * (6 * zz - 3 * xx - 3 * yy);
  bx[13] = sh_constant<T>(kC3[4]) * (4 * zz - 3 * xx - yy),
  by[13] = sh_constant<T>(kC3[4]) * (-2 * x * y), bz[13] = sh_constant<T>(kC3[4]) * 8 * x * z;
  bx[14] = sh_constant<T>(kC3[5]) * 2 * x * z, by[14] = sh_constant<T>(kC3[5]) * (-2 * y * z),
  bz[14] = sh_constant<T>(kC3[5]) * (xx - yy);
  bx[15] = sh_constant<T>(kC3[6]) * (3 * xx - 3 * yy),
  by[15] = sh_constant<T>(kC3[6]) * (-6 * x * y), bz[15] = zero;
}

// The unit view direction from the camera centre to a mean (+Z when they coincide) and their
// distance.
template <class T>
inline Eigen::Matrix<T, 3, 1> view_direction(const Eigen::Matrix<T, 3, 1>& mean,
                                             const Eigen::Matrix<T, 3, 1>& centre, T* dist) {
  using V3 = Eigen::Matrix<T, 3, 1>;
  const V3 d = mean - centre;
  *dist = d.norm();
  return *dist > 0 ? V3(d / *dist) : V3(0, 0, 1);
}

// RGB = sum_k Y_k(dir) coeffs[k] + 0.5 per channel, clamped at 0 (clamped[ch] = 1 where the sum
// was negative). coeffs: (deg + 1)^2 x 3, [k][rgb].
template <class T, class C>
inline void sh_to_color(int deg, const C* coeffs, const Eigen::Matrix<T, 3, 1>& dir, T* rgb,
                        uint8_t* clamped) {
  const int K = (deg + 1) * (deg + 1);
  T b[16];
  basis<T>(deg, dir.x(), dir.y(), dir.z(), b);
  for (int ch = 0; ch < 3; ++ch) {
    T c = T(0.5);
    for (int k = 0; k < K; ++k) c += b[k] * T(coeffs[k * 3 + ch]);
    clamped[ch] = c < 0;
    rgb[ch] = std::max(c, T(0));
  }
}

// From d rgb: d coeffs (written, K x 3) and d mean through the view direction (added to dmean;
// dist = |mean - centre| as view_direction returned it).
template <class T, class C>
inline void sh_to_color_backward(int deg, const C* coeffs, const Eigen::Matrix<T, 3, 1>& dir,
                                 T dist, const uint8_t* clamped, const T* drgb, T* dcoeffs,
                                 Eigen::Matrix<T, 3, 1>& dmean) {
  using V3 = Eigen::Matrix<T, 3, 1>;
  const int K = (deg + 1) * (deg + 1);
  T gcol[3];
  for (int ch = 0; ch < 3; ++ch) gcol[ch] = clamped[ch] ? T(0) : drgb[ch];
  T b[16];
  basis<T>(deg, dir.x(), dir.y(), dir.z(), b);
  for (int k = 0; k < K; ++k)
    for (int ch = 0; ch < 3; ++ch) dcoeffs[k * 3 + ch] = b[k] * gcol[ch];
  if (deg > 0 && dist > 0) {
    T bx[16], by[16], bz[16];
    basis_grad<T>(deg, dir.x(), dir.y(), dir.z(), bx, by, bz);
    V3 gdir = V3::Zero();
    for (int k = 1; k < K; ++k) {
      T w = 0;
      for (int ch = 0; ch < 3; ++ch) w += T(coeffs[k * 3 + ch]) * gcol[ch];
      gdir += w * V3(bx[k], by[k], bz[k]);
    }
    dmean += (gdir - dir * dir.dot(gdir)) / dist;
  }
}

}  // namespace ks::sh
