#pragma once
// Rotations, one implementation each: axis-angle -> matrix (Rodrigues) with its analytic
// backward, matrix -> axis-angle, and quaternions (w, x, y, z).
//
// axis_angle_to_matrix is templated on the scalar so that the same code serves double (the body
// model, playback), float, and ceres::Jet (automatic differentiation in a least-squares fit):
// it calls sqrt / sin / cos unqualified (std:: for built-in types, argument-dependent lookup for
// Jets) and branches only on the squared angle, below kSmallAngle2 using the Taylor series of its
// coefficients, so neither the value nor the derivatives divide by zero at the identity.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

namespace ks {

// Below this squared angle (rad^2) Rodrigues' coefficients are evaluated by their Taylor series.
inline constexpr double kSmallAngle2 = 1e-12;

// The skew-symmetric cross-product matrix: skew(v) u = v x u.
template <class T>
Eigen::Matrix<T, 3, 3> skew(const Eigen::Matrix<T, 3, 1>& v) {
  Eigen::Matrix<T, 3, 3> K;
  K << T(0), -v.z(), v.y(), v.z(), T(0), -v.x(), -v.y(), v.x(), T(0);
  return K;
}

// Rodrigues: R = I + a K + b K^2 with K = skew(aa) (the unnormalised axis), theta = |aa|,
// a = sin(theta) / theta, b = (1 - cos(theta)) / theta^2 (series below kSmallAngle2).
template <class T>
Eigen::Matrix<T, 3, 3> axis_angle_to_matrix(const Eigen::Matrix<T, 3, 1>& aa) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  const Eigen::Matrix<T, 3, 3> K = skew(aa);
  const T t2 = aa.squaredNorm();
  T a, b;
  if (t2 < T(kSmallAngle2)) {
    a = T(1) - t2 / T(6);
    b = T(0.5) - t2 / T(24);
  } else {
    const T th = sqrt(t2);
    a = sin(th) / th;
    b = (T(1) - cos(th)) / (th * th);
  }
  return Eigen::Matrix<T, 3, 3>::Identity() + a * K + b * K * K;
}

// The double version for arguments that are Eigen expressions (e.g. pose.row(j).transpose()).
inline Eigen::Matrix3d axis_angle_to_matrix(const Eigen::Vector3d& aa) {
  return axis_angle_to_matrix<double>(aa);
}

// The backward of axis_angle_to_matrix (double or float): d loss / d aa from dR = d loss / d R.
// The derivative coefficients a'/theta and b'/theta use their series below theta^2 = 1e-4
// (where the closed forms lose digits to cancellation).
template <class T>
Eigen::Matrix<T, 3, 1> axis_angle_to_matrix_backward(const Eigen::Matrix<T, 3, 1>& aa,
                                                     const Eigen::Matrix<T, 3, 3>& dR) {
  using M3 = Eigen::Matrix<T, 3, 3>;
  using V3 = Eigen::Matrix<T, 3, 1>;
  const M3 K = skew(aa);
  const T t2 = aa.squaredNorm();
  T a, b;
  if (t2 < T(kSmallAngle2)) {
    a = T(1) - t2 / T(6);
    b = T(0.5) - t2 / T(24);
  } else {
    const T th = std::sqrt(t2);
    a = std::sin(th) / th;
    b = (T(1) - std::cos(th)) / (th * th);
  }
  T ca, cb;  // a'(theta) / theta and b'(theta) / theta
  if (t2 < T(1e-4)) {
    ca = T(-1) / T(3) + t2 / T(30) - t2 * t2 / T(840);
    cb = T(-1) / T(12) + t2 / T(180) - t2 * t2 / T(6720);
  } else {
    const T th = std::sqrt(t2), s = std::sin(th), c = std::cos(th);
    ca = (th * c - s) / (t2 * th);
    cb = (th * s - T(2) * (T(1) - c)) / (t2 * t2);
  }
  // <dR, E_i> for the generators E_i = skew(e_i).
  auto vee = [](const M3& M) {
    return V3(M(2, 1) - M(1, 2), M(0, 2) - M(2, 0), M(1, 0) - M(0, 1));
  };
  const T dK = (dR.array() * K.array()).sum();
  const T dK2 = (dR.array() * (K * K).array()).sum();
  // d(K^2)/d aa_i = E_i K + K E_i, and <dR, E K> + <dR, K E> = <dR K^T + K^T dR, E>.
  return (ca * dK + cb * dK2) * aa + a * vee(dR) +
         b * vee(M3(dR * K.transpose() + K.transpose() * dR));
}

// The axis-angle of a rotation matrix (angle in [0, pi]).
inline Eigen::Vector3d matrix_to_axis_angle(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd a(R);
  return a.angle() * a.axis();
}

// The rotation a share w in [0, 1] of the way from axis-angle a to b along the shortest arc
// (spherical linear interpolation): R_a exp(w log(R_a^T R_b)).
inline Eigen::Vector3d interpolate_axis_angle(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                              double w) {
  const Eigen::Matrix3d Ra = axis_angle_to_matrix(a);
  const Eigen::Vector3d d = matrix_to_axis_angle(Ra.transpose() * axis_angle_to_matrix(b));
  return matrix_to_axis_angle(Ra * axis_angle_to_matrix(Eigen::Vector3d(w * d)));
}

// Hamilton product out = a * b of quaternions (w, x, y, z). `out` must not alias a or b.
template <class T>
inline void quat_mul(const T* a, const T* b, T* out) {
  out[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3];
  out[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2];
  out[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1];
  out[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0];
}

// The rotation matrix of a unit quaternion (w, x, y, z).
template <class T>
inline Eigen::Matrix<T, 3, 3> quat_to_matrix(T w, T x, T y, T z) {
  Eigen::Matrix<T, 3, 3> R;
  R << 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),  //
      2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),   //
      2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y);
  return R;
}

// The unit quaternions (w, x, y, z) of CW matrices close to rotations (e.g. blends of skinning
// rotations) at once, L a core/simd.hpp Lanes: Shepperd's case split as Eigen's conversion makes
// it (the trace when positive, else the largest diagonal entry), each lane's case chosen by
// selects instead of branches, then normalised. m: row-major 3 x 3, one vector per entry.
template <class L>
inline void matrix_to_quat(const typename L::V* m, typename L::V* q) {
  using V = typename L::V;
  using I = typename L::I;
  const V m00 = m[0], m01 = m[1], m02 = m[2], m10 = m[3], m11 = m[4], m12 = m[5], m20 = m[6],
          m21 = m[7], m22 = m[8];
  const I cw = m00 + m11 + m22 > 0.0f;
  const I y_over_x = m11 > m00;  // Eigen: i = argmax of the diagonal, the first of ties
  const I cz = ~cw & (m22 > L::sel(y_over_x, m11, m00));
  const I cy = ~cw & ~cz & y_over_x;
  const I cx = ~cw & ~cz & ~cy;
  const V one = L::splat(1.f);
  const V s = L::sel(
      cw, m00 + m11 + m22 + one,
      L::sel(cx, m00 - m11 - m22 + one, L::sel(cy, m11 - m22 - m00 + one, m22 - m00 - m11 + one)));
  const V r = L::sqrt(s), h = 0.5f / r, big = 0.5f * r;
  const V a = m21 - m12, b = m02 - m20, c = m10 - m01, d = m10 + m01, e = m20 + m02, f = m21 + m12;
  const V w = L::sel(cw, big, L::sel(cx, a, L::sel(cy, b, c)) * h);
  const V x = L::sel(cx, big, L::sel(cw, a, L::sel(cy, d, e)) * h);
  const V y = L::sel(cy, big, L::sel(cw, b, L::sel(cx, d, f)) * h);
  const V z = L::sel(cz, big, L::sel(cw, c, L::sel(cx, e, f)) * h);
  const V n = L::sqrt(w * w + x * x + y * y + z * z);
  q[0] = w / n, q[1] = x / n, q[2] = y / n, q[3] = z / n;
}

// The backward of matrix_to_quat for one matrix (double): d loss / d m (row-major 3 x 3) from
// dq = d loss / d q, with the forward's case split (the trace when positive, else the largest
// diagonal entry) and normalisation. Overwrites dm.
inline void matrix_to_quat_backward(const double* m, const double* dq, double* dm) {
  const double m00 = m[0], m01 = m[1], m02 = m[2], m10 = m[3], m11 = m[4], m12 = m[5], m20 = m[6],
               m21 = m[7], m22 = m[8];
  int c;  // the unnormalised quaternion's large entry: 0 (w, the trace case), 1 (x), 2 (y), 3 (z)
  if (m00 + m11 + m22 > 0.0)
    c = 0;
  else if (m22 > (m11 > m00 ? m11 : m00))
    c = 3;
  else
    c = m11 > m00 ? 2 : 1;
  // s = 1 + sign . diag, u[c] = r / 2, u[k] = P_k / (2 r) for the three others (r = sqrt(s)).
  static constexpr double kSign[4][3] = {{1, 1, 1}, {1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}};
  const double s = 1.0 + kSign[c][0] * m00 + kSign[c][1] * m11 + kSign[c][2] * m22;
  const double r = std::sqrt(s), h = 0.5 / r;
  // P for each entry k != c: a = m21 - m12 (w, x), b = m02 - m20 (w, y), c = m10 - m01 (w, z),
  // d = m10 + m01 (x, y), e = m20 + m02 (x, z), f = m21 + m12 (y, z).
  const double a = m21 - m12, b = m02 - m20, cc = m10 - m01, d = m10 + m01, e = m20 + m02,
               f = m21 + m12;
  static constexpr int kP[4][4] = {{-1, 0, 1, 2}, {0, -1, 3, 4}, {1, 3, -1, 5}, {2, 4, 5, -1}};
  const double P[6] = {a, b, cc, d, e, f};
  double u[4];
  for (int k = 0; k < 4; ++k) u[k] = k == c ? 0.5 * r : P[kP[c][k]] * h;
  const double n = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2] + u[3] * u[3]);
  double qd = 0;
  for (int k = 0; k < 4; ++k) qd += u[k] / n * dq[k];
  double du[4];
  for (int k = 0; k < 4; ++k) du[k] = (dq[k] - u[k] / n * qd) / n;
  // dr/ds = 1 / (2 r), dh/ds = -h / (2 s).
  double ds = du[c] * 0.25 / r, dP[6] = {0, 0, 0, 0, 0, 0};
  for (int k = 0; k < 4; ++k) {
    if (k == c) continue;
    dP[kP[c][k]] = du[k] * h;
    ds += du[k] * P[kP[c][k]] * (-h / (2.0 * s));
  }
  for (int k = 0; k < 9; ++k) dm[k] = 0;
  dm[0] += kSign[c][0] * ds, dm[4] += kSign[c][1] * ds, dm[8] += kSign[c][2] * ds;
  dm[7] += dP[0], dm[5] -= dP[0];  // a
  dm[2] += dP[1], dm[6] -= dP[1];  // b
  dm[3] += dP[2], dm[1] -= dP[2];  // c
  dm[3] += dP[3], dm[1] += dP[3];  // d
  dm[6] += dP[4], dm[2] += dP[4];  // e
  dm[7] += dP[5], dm[5] += dP[5];  // f
}

}  // namespace ks
