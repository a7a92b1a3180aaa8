#pragma once
// Real spherical harmonics of degree 0..3 with the constants and signs of the original 3DGS code,
// and their derivatives with respect to the (unit) direction. Templated for float/double.

namespace ks::sh {

constexpr double kC0 = 0.28209479177387814;
constexpr double kC1 = 0.4886025119029199;
constexpr double kC2[5] = {1.0925484305920792, -1.0925484305920792, 0.31539156525252005,
                           -1.0925484305920792, 0.5462742152960396};
constexpr double kC3[7] = {-0.5900435899266435, 2.890611442640554,   -0.4570457994644658,
                           0.3731763325901154,  -0.4570457994644658, 1.445305721320277,
                           -0.5900435899266435};

// b[k] for k < (deg+1)^2.
template <class T>
inline void basis(int deg, T x, T y, T z, T* b) {
  b[0] = T(kC0);
  if (deg < 1) return;
  b[1] = T(-kC1) * y;
  b[2] = T(kC1) * z;
  b[3] = T(-kC1) * x;
  if (deg < 2) return;
  const T xx = x * x, yy = y * y, zz = z * z;
  b[4] = T(kC2[0]) * x * y;
  b[5] = T(kC2[1]) * y * z;
  b[6] = T(kC2[2]) * (2 * zz - xx - yy);
  b[7] = T(kC2[3]) * x * z;
  b[8] = T(kC2[4]) * (xx - yy);
  if (deg < 3) return;
  b[9] = T(kC3[0]) * y * (3 * xx - yy);
  b[10] = T(kC3[1]) * x * y * z;
  b[11] = T(kC3[2]) * y * (4 * zz - xx - yy);
  b[12] = T(kC3[3]) * z * (2 * zz - 3 * xx - 3 * yy);
  b[13] = T(kC3[4]) * x * (4 * zz - xx - yy);
  b[14] = T(kC3[5]) * z * (xx - yy);
  b[15] = T(kC3[6]) * x * (xx - 3 * yy);
}

// Partial derivatives of b[k] with respect to x, y, z (treated as independent).
template <class T>
inline void basis_grad(int deg, T x, T y, T z, T* bx, T* by, T* bz) {
  bx[0] = by[0] = bz[0] = 0;
  if (deg < 1) return;
  const T c1 = T(kC1);
  bx[1] = 0, by[1] = -c1, bz[1] = 0;
  bx[2] = 0, by[2] = 0, bz[2] = c1;
  bx[3] = -c1, by[3] = 0, bz[3] = 0;
  if (deg < 2) return;
  const T xx = x * x, yy = y * y, zz = z * z;
  bx[4] = T(kC2[0]) * y, by[4] = T(kC2[0]) * x, bz[4] = 0;
  bx[5] = 0, by[5] = T(kC2[1]) * z, bz[5] = T(kC2[1]) * y;
  bx[6] = T(-2 * kC2[2]) * x, by[6] = T(-2 * kC2[2]) * y, bz[6] = T(4 * kC2[2]) * z;
  bx[7] = T(kC2[3]) * z, by[7] = 0, bz[7] = T(kC2[3]) * x;
  bx[8] = T(2 * kC2[4]) * x, by[8] = T(-2 * kC2[4]) * y, bz[8] = 0;
  if (deg < 3) return;
  bx[9] = T(kC3[0]) * 6 * x * y, by[9] = T(kC3[0]) * (3 * xx - 3 * yy), bz[9] = 0;
  bx[10] = T(kC3[1]) * y * z, by[10] = T(kC3[1]) * x * z, bz[10] = T(kC3[1]) * x * y;
  bx[11] = T(kC3[2]) * (-2 * x * y), by[11] = T(kC3[2]) * (4 * zz - xx - 3 * yy),
  bz[11] = T(kC3[2]) * 8 * y * z;
  bx[12] = T(kC3[3]) * (-6 * x * z), by[12] = T(kC3[3]) * (-6 * y * z),
  bz[12] = T(kC3[3]) * (6 * zz - 3 * xx - 3 * yy);
  bx[13] = T(kC3[4]) * (4 * zz - 3 * xx - yy), by[13] = T(kC3[4]) * (-2 * x * y),
  bz[13] = T(kC3[4]) * 8 * x * z;
  bx[14] = T(kC3[5]) * 2 * x * z, by[14] = T(kC3[5]) * (-2 * y * z), bz[14] = T(kC3[5]) * (xx - yy);
  bx[15] = T(kC3[6]) * (3 * xx - 3 * yy), by[15] = T(kC3[6]) * (-6 * x * y), bz[15] = 0;
}

}  // namespace ks::sh
