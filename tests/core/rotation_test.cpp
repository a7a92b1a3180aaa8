// Rotations (core/rotation.hpp): Rodrigues against Eigen and across its small-angle switch, its
// backward against finite differences, the same template on ceres::Jet (where Ceres is
// installed), quaternion helpers against Eigen.
#include "core/rotation.hpp"
#include "core/simd.hpp"

#include <gtest/gtest.h>

#include <random>

#include "grad_check.hpp"

#if __has_include(<ceres/jet.h>)
#include <ceres/jet.h>
#define KS_TEST_HAVE_JET 1
#endif

namespace ks {
namespace {

TEST(Rotation, RodriguesMatchesEigenAndIsOrthonormal) {
  std::mt19937_64 rng(1);
  for (int t = 0; t < 100; ++t) {
    const auto v = test::randv(3, rng, -3, 3);
    const Eigen::Vector3d aa(v[0], v[1], v[2]);
    const Eigen::Matrix3d R = axis_angle_to_matrix(aa);
    const Eigen::Matrix3d E = Eigen::AngleAxisd(aa.norm(), aa.normalized()).toRotationMatrix();
    EXPECT_LT((R - E).cwiseAbs().maxCoeff(), 1e-14);
    EXPECT_LT((R * R.transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-14);
    EXPECT_NEAR(R.determinant(), 1.0, 1e-14);
    // Back to axis-angle (unique below pi).
    if (aa.norm() < M_PI) {
      EXPECT_LT((matrix_to_axis_angle(R) - aa).norm(), 1e-12);
    }
  }
  EXPECT_EQ(axis_angle_to_matrix(Eigen::Vector3d::Zero()), Eigen::Matrix3d::Identity());
}

TEST(Rotation, RodriguesIsContinuousAcrossTheSmallAngleSwitch) {
  const Eigen::Vector3d axis = Eigen::Vector3d(1, -2, 0.5).normalized();
  const double th = std::sqrt(kSmallAngle2);
  for (double s : {0.999999, 1.000001}) {
    const Eigen::Vector3d aa = th * s * axis;
    const Eigen::Matrix3d E = Eigen::AngleAxisd(aa.norm(), axis).toRotationMatrix();
    EXPECT_LT((axis_angle_to_matrix(aa) - E).cwiseAbs().maxCoeff(), 1e-15) << s;
  }
  // Float works too.
  const Eigen::Matrix3f Rf = axis_angle_to_matrix<float>(Eigen::Vector3f(0.3f, -0.2f, 0.9f));
  const Eigen::Matrix3d Rd = axis_angle_to_matrix(Eigen::Vector3d(0.3, -0.2, 0.9));
  EXPECT_LT((Rf.cast<double>() - Rd).cwiseAbs().maxCoeff(), 1e-6);
}

TEST(Rotation, RodriguesBackwardMatchesFiniteDifferences) {
  std::mt19937_64 rng(2);
  std::vector<Eigen::Vector3d> points = {Eigen::Vector3d::Zero(), Eigen::Vector3d(1e-8, -2e-8, 0),
                                         Eigen::Vector3d(3e-3, 1e-3, -2e-3),
                                         Eigen::Vector3d(0, 0, 3.1)};
  for (int t = 0; t < 20; ++t) {
    const auto v = test::randv(3, rng, -2, 2);
    points.emplace_back(v[0], v[1], v[2]);
  }
  for (const Eigen::Vector3d& aa : points) {
    const auto w = test::randv(9, rng);
    const Eigen::Matrix3d dR = Eigen::Map<const Eigen::Matrix3d>(w.data());
    const Eigen::Vector3d g = axis_angle_to_matrix_backward<double>(aa, dR);
    test::expect_grad(
        [&](const std::vector<double>& x) {
          return (axis_angle_to_matrix(Eigen::Vector3d(x[0], x[1], x[2])).array() * dR.array())
              .sum();
        },
        {aa.x(), aa.y(), aa.z()}, {g.x(), g.y(), g.z()}, 1e-6, 1e-8);
  }
}

#ifdef KS_TEST_HAVE_JET
TEST(Rotation, RodriguesOnJetsGivesTheAnalyticDerivatives) {
  using J3 = ceres::Jet<double, 3>;
  const std::vector<Eigen::Vector3d> points = {
      Eigen::Vector3d::Zero(), Eigen::Vector3d(0.4, -1.1, 0.7), Eigen::Vector3d(1e-9, 0, 0)};
  for (const Eigen::Vector3d& aa : points) {
    Eigen::Matrix<J3, 3, 1> a;
    for (int k = 0; k < 3; ++k) a[k] = J3(aa[k], k);
    const Eigen::Matrix<J3, 3, 3> R = axis_angle_to_matrix<J3>(a);
    const Eigen::Matrix3d Rd = axis_angle_to_matrix(aa);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(R(r, c).a, Rd(r, c), 1e-15);
        // The derivative of R(r, c) is the backward of a one-hot dR.
        Eigen::Matrix3d dR = Eigen::Matrix3d::Zero();
        dR(r, c) = 1;
        const Eigen::Vector3d g = axis_angle_to_matrix_backward<double>(aa, dR);
        for (int k = 0; k < 3; ++k) EXPECT_NEAR(R(r, c).v[k], g[k], 1e-12) << r << c << k;
      }
  }
}
#endif

TEST(Rotation, MatrixToQuatTakesEachOfShepperdsCases) {
  // A small rotation (the trace case) and half-turns nearly about x, y and z (the diagonal cases).
  using L = Lanes<4>;
  const Eigen::Vector3d axes[4] = {
      {0.3, -0.5, 0.8}, {1, 0.05, -0.02}, {0.03, 1, 0.04}, {-0.02, 0.05, 1}};
  const double angles[4] = {0.2, 3.0, 3.0, 3.0};
  L::V m[9], q[4];
  Eigen::Quaterniond ref[4];
  for (int l = 0; l < 4; ++l) {
    ref[l] = Eigen::Quaterniond(Eigen::AngleAxisd(angles[l], axes[l].normalized()));
    const Eigen::Matrix3d R = ref[l].toRotationMatrix();
    for (int e = 0; e < 9; ++e) m[e][l] = float(R(e / 3, e % 3));
  }
  matrix_to_quat<L>(m, q);
  for (int l = 0; l < 4; ++l) {
    const double s =
        q[0][l] * ref[l].w() + q[1][l] * ref[l].x() + q[2][l] * ref[l].y() + q[3][l] * ref[l].z();
    EXPECT_NEAR(std::abs(s), 1.0, 1e-6) << l;
  }
}

TEST(Rotation, QuaternionsMatchEigen) {
  std::mt19937_64 rng(3);
  for (int t = 0; t < 50; ++t) {
    const auto v = test::randv(8, rng);
    const Eigen::Quaterniond a = Eigen::Quaterniond(v[0], v[1], v[2], v[3]).normalized();
    const Eigen::Quaterniond b = Eigen::Quaterniond(v[4], v[5], v[6], v[7]).normalized();
    const double qa[4] = {a.w(), a.x(), a.y(), a.z()}, qb[4] = {b.w(), b.x(), b.y(), b.z()};
    double qc[4];
    quat_mul(qa, qb, qc);
    const Eigen::Quaterniond c = a * b;
    EXPECT_NEAR(qc[0], c.w(), 1e-14);
    EXPECT_NEAR(qc[1], c.x(), 1e-14);
    EXPECT_NEAR(qc[2], c.y(), 1e-14);
    EXPECT_NEAR(qc[3], c.z(), 1e-14);
    EXPECT_LT((quat_to_matrix(a.w(), a.x(), a.y(), a.z()) - a.toRotationMatrix()).norm(), 1e-14);
    // Back from the matrix (up to sign); from a shrunk blend of rotations still a unit
    // quaternion near the rotation's.
    // Four lanes: the rotation, a shrunk copy, and the two again transposed (the inverse).
    using L = Lanes<4>;
    L::V m[9], q[4];
    const Eigen::Matrix3d Ra = a.toRotationMatrix();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c)
        m[3 * r + c] =
            L::V{float(Ra(r, c)), float(0.97 * Ra(r, c)), float(Ra(c, r)), float(0.97 * Ra(c, r))};
    matrix_to_quat<L>(m, q);
    for (int l = 0; l < 4; ++l) {
      const double sx = l < 2 ? 1.0 : -1.0;  // the inverse: conjugate
      const double dot =
          q[0][l] * a.w() + sx * (q[1][l] * a.x() + q[2][l] * a.y() + q[3][l] * a.z());
      EXPECT_NEAR(std::abs(dot), 1.0, l % 2 ? 1e-3 : 1e-6) << l;
      EXPECT_NEAR(q[0][l] * q[0][l] + q[1][l] * q[1][l] + q[2][l] * q[2][l] + q[3][l] * q[3][l],
                  1.0, 1e-6);
      // Against Eigen's conversion, up to sign.
      Eigen::Matrix3d Rl;
      for (int e = 0; e < 9; ++e) Rl(e / 3, e % 3) = m[e][l];
      const Eigen::Quaterniond ref = Eigen::Quaterniond(Rl).normalized();
      const double s =
          q[0][l] * ref.w() + q[1][l] * ref.x() + q[2][l] * ref.y() + q[3][l] * ref.z();
      EXPECT_NEAR(std::abs(s), 1.0, 1e-6) << l;
    }
  }
}

// Interpolation along the shortest arc: the ends, half of one rotation about an axis, and half
// way between two rotations the same angle from either end.
TEST(Rotation, InterpolateAxisAngle) {
  const Eigen::Vector3d a(0.3, -0.2, 0.5), b(-0.4, 0.9, 0.1);
  EXPECT_LT(
      (axis_angle_to_matrix(interpolate_axis_angle(a, b, 0.0)) - axis_angle_to_matrix(a)).norm(),
      1e-12);
  EXPECT_LT(
      (axis_angle_to_matrix(interpolate_axis_angle(a, b, 1.0)) - axis_angle_to_matrix(b)).norm(),
      1e-12);
  EXPECT_LT((interpolate_axis_angle(Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 1.2, 0), 0.5) -
             Eigen::Vector3d(0, 0.6, 0))
                .norm(),
            1e-12);
  const Eigen::Matrix3d m = axis_angle_to_matrix(interpolate_axis_angle(a, b, 0.5));
  const double da = matrix_to_axis_angle(axis_angle_to_matrix(a).transpose() * m).norm();
  const double db = matrix_to_axis_angle(m.transpose() * axis_angle_to_matrix(b)).norm();
  EXPECT_NEAR(da, db, 1e-9);
}

TEST(Rotation, MatrixToQuatBackwardMatchesFiniteDifferences) {
  // Each of Shepperd's cases (a small rotation, half-turns nearly about x, y, z), on rotations
  // and on shrunk, perturbed blends; the forward in double is Eigen's conversion normalised (the
  // same case split as matrix_to_quat, checked above), its sign fixed by the unperturbed one's.
  std::mt19937_64 rng(11);
  const Eigen::Vector3d axes[4] = {
      {0.3, -0.5, 0.8}, {1, 0.05, -0.02}, {0.03, 1, 0.04}, {-0.02, 0.05, 1}};
  const double angles[4] = {0.4, 3.0, 3.0, 3.0};
  for (int c = 0; c < 4; ++c)
    for (int blend = 0; blend < 2; ++blend) {
      Eigen::Matrix3d R = Eigen::AngleAxisd(angles[c], axes[c].normalized()).toRotationMatrix();
      if (blend) {
        const auto v = test::randv(9, rng, -0.03, 0.03);
        R *= 0.93;
        for (int e = 0; e < 9; ++e) R(e / 3, e % 3) += v[size_t(e)];
      }
      const Eigen::Quaterniond q0 = Eigen::Quaterniond(R).normalized();
      const auto dq = test::randv(4, rng);
      auto f = [&](const std::vector<double>& m) {
        Eigen::Matrix3d M;
        for (int e = 0; e < 9; ++e) M(e / 3, e % 3) = m[size_t(e)];
        Eigen::Quaterniond q = Eigen::Quaterniond(M).normalized();
        if (q.dot(q0) < 0) q.coeffs() *= -1.0;
        return q.w() * dq[0] + q.x() * dq[1] + q.y() * dq[2] + q.z() * dq[3];
      };
      std::vector<double> m(9), g(9);
      for (int e = 0; e < 9; ++e) m[size_t(e)] = R(e / 3, e % 3);
      // Our quaternion's sign is the one Eigen's gives (both take the same case's root).
      matrix_to_quat_backward(m.data(), dq.data(), g.data());
      test::expect_grad(f, m, g, 1e-6, 1e-6);
    }
}

}  // namespace
}  // namespace ks
