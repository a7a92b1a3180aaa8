// Linear blend skinning (body/lbs.hpp): the backward against finite differences through the
// forward, a rigid skin, and playback posing (avatar file: its own skeleton, float pose
// correctives) against the training's (body model: body_forward's transforms and correctives)
// through the same LBS.
#include "body/lbs.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

#include "avatar/from_body.hpp"
#include "avatar/pose.hpp"
#include "body/body_model.hpp"
#include "core/error.hpp"
#include "grad_check.hpp"

namespace ks {
namespace {

std::vector<Eigen::Matrix4d> random_transforms(int J, std::mt19937_64& rng) {
  std::vector<Eigen::Matrix4d> T(static_cast<size_t>(J));
  for (int j = 0; j < J; ++j) {
    auto r = test::randv(4, rng);
    Eigen::Quaterniond q(r[0] + 2, r[1], r[2], r[3]);
    q.normalize();
    T[size_t(j)].setIdentity();
    T[size_t(j)].topLeftCorner<3, 3>() = q.toRotationMatrix();
    auto t = test::randv(3, rng);
    T[size_t(j)].block<3, 1>(0, 3) = Eigen::Vector3d(t[0], t[1], t[2]);
  }
  return T;
}

// n canonical Gaussians with random means, log-scales, opacities and SH, unit rotations.
Gaussians random_canonical(int n, int sh_degree, std::mt19937_64& rng) {
  Gaussians c;
  c.sh_degree = sh_degree;
  c.resize(size_t(n));
  for (float& v : c.means) v = float(test::randv(1, rng)[0]);
  for (float& v : c.log_scales) v = float(test::randv(1, rng)[0]) - 3.f;
  for (float& v : c.opacity_logits) v = float(test::randv(1, rng)[0]);
  for (float& v : c.sh) v = float(test::randv(1, rng)[0]);
  for (int i = 0; i < n; ++i) c.quats[4 * size_t(i)] = 1.f;
  return c;
}

TEST(Lbs, BackwardMatchesFiniteDifferences) {
  std::mt19937_64 rng(3);
  const int n = 12, J = 5;
  const auto T = random_transforms(J, rng);
  Gaussians c;
  c.resize(n);
  std::vector<int> sj(4 * n);
  std::vector<float> sw(4 * n);
  for (int i = 0; i < n; ++i) {
    auto w = test::randv(4, rng, 0.1, 1);
    double s = w[0] + w[1] + w[2] + w[3];
    for (int k = 0; k < 4; ++k) sj[4 * i + k] = (i + k) % J, sw[4 * i + k] = float(w[k] / s);
  }
  auto m0 = test::randv(3 * n, rng), q0 = test::randv(4 * n, rng),
       po = test::randv(3 * n, rng, -0.1, 0.1);
  std::vector<float> pof(po.begin(), po.end());
  auto wm = test::randv(3 * n, rng), wq = test::randv(4 * n, rng);
  // Float pipeline: a loose tolerance with a larger step.
  auto f = [&](const std::vector<double>& x) {
    Gaussians g = c, posed;
    for (int i = 0; i < 3 * n; ++i) g.means[i] = float(x[i]);
    for (int i = 0; i < 4 * n; ++i) g.quats[i] = float(x[3 * n + i]);
    lbs_forward(g, pof.data(), sj, sw, T, posed);
    double s = 0;
    for (int i = 0; i < 3 * n; ++i) s += wm[i] * posed.means[i];
    for (int i = 0; i < 4 * n; ++i) s += wq[i] * posed.quats[i];
    return s;
  };
  std::vector<double> x(m0);
  x.insert(x.end(), q0.begin(), q0.end());
  Gaussians g = c, posed;
  for (int i = 0; i < 3 * n; ++i) g.means[i] = float(m0[i]);
  for (int i = 0; i < 4 * n; ++i) g.quats[i] = float(q0[i]);
  LbsCache cache;
  lbs_forward(g, pof.data(), sj, sw, T, posed, &cache);
  std::vector<float> dmp(wm.begin(), wm.end()), dqp(wq.begin(), wq.end()), dmc, dqc;
  lbs_backward(cache, dmp, dqp, dmc, dqc);
  std::vector<double> grad(dmc.begin(), dmc.end());
  grad.insert(grad.end(), dqc.begin(), dqc.end());
  test::expect_grad(f, x, grad, 1e-2, 2e-3, 1000);
  // A rigid single-joint skin reproduces the joint transform exactly.
  std::fill(sw.begin(), sw.end(), 0.f);
  for (int i = 0; i < n; ++i) sw[4 * i] = 1.f;
  lbs_forward(g, nullptr, sj, sw, T, posed);
  for (int i = 0; i < n; ++i) {
    Eigen::Vector4d p(m0[3 * i], m0[3 * i + 1], m0[3 * i + 2], 1.0);
    Eigen::Vector4d e = T[sj[4 * i]] * p;
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(posed.means[3 * i + k], e[k], 1e-5);
  }
  EXPECT_THROW(lbs_forward(g, nullptr, std::vector<int>(3), sw, T, posed), Error);
}

TEST(Lbs, PlaybackPosesAsTraining) {
  // The default body with (made-up) pose correctives, so that both paths carry them.
  BodyModel model = default_body_model();
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-0.01, 0.01);
  for (Eigen::Index i = 0; i < model.posedirs.size(); ++i) model.posedirs.data()[i] = u(rng);
  model.update_posedirs_flag();
  Eigen::VectorXd betas = Eigen::VectorXd::Zero(std::min(model.num_betas, 3));
  betas[0] = 0.7;
  PlainAvatarOptions opt;
  opt.subdivide = 0;
  const Avatar a = avatar_from_body(model, betas, opt);
  ASSERT_GT(a.posedirs.size(), 0);
  BodyParams p;
  p.betas = betas;
  p.global_orient = Eigen::Vector3d(0.2, -0.4, 0.1);
  p.body_pose = Eigen::VectorXd::Zero(3 * model.num_body_pose_joints());
  for (int k = 0; k < p.body_pose.size(); ++k) p.body_pose[k] = 0.5 * u(rng) * 60;
  p.transl = Eigen::Vector3d(0.1, 0.2, -0.3);
  // Training: the body model's transforms and correctives (the avatar's template is the body's).
  const BodyState bs = body_forward(model, p);
  const int n = a.num_gaussians();
  std::vector<float> pose_off(3 * size_t(n));
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) pose_off[3 * size_t(i) + k] = float(bs.pose_offsets(i, k));
  Gaussians trained;
  lbs_forward(a.gaussians, pose_off.data(), a.skin_joints, a.skin_weights, bs.transforms, trained);
  // Playback: the avatar file alone.
  const Gaussians played = pose_avatar(a, p);
  ASSERT_EQ(played.means.size(), trained.means.size());
  float dm = 0, dq = 0;
  for (size_t q = 0; q < played.means.size(); ++q)
    dm = std::max(dm, std::abs(played.means[q] - trained.means[q]));
  for (size_t q = 0; q < played.quats.size(); ++q)
    dq = std::max(dq, std::abs(played.quats[q] - trained.quats[q]));
  EXPECT_LT(dm, 1e-6f);  // float pose correctives in the file, double in the model
  EXPECT_EQ(dq, 0.f);    // the same transforms, the same blend
  EXPECT_EQ(played.opacity_logits, trained.opacity_logits);
  // The correctives matter here: without them playback would be off.
  Gaussians bare;
  lbs_forward(a.gaussians, nullptr, a.skin_joints, a.skin_weights, bs.transforms, bare);
  float off = 0;
  for (size_t q = 0; q < bare.means.size(); ++q)
    off = std::max(off, std::abs(bare.means[q] - trained.means[q]));
  EXPECT_GT(off, 1e-3f);
}

TEST(Lbs, KeepUnposedWritesWhatThePoseChanges) {
  std::mt19937_64 rng(9);
  const int n = 50, J = 3, K = 2;
  const Gaussians c = random_canonical(n, 1, rng);
  std::vector<int> sj(size_t(n) * K);
  std::vector<float> sw(size_t(n) * K, 0.5f);
  for (size_t q = 0; q < sj.size(); ++q) sj[q] = int(q % J);
  const auto T1 = random_transforms(J, rng), T2 = random_transforms(J, rng);
  Gaussians fresh, kept;
  lbs_forward(c, nullptr, sj, sw, T2, fresh);
  // Kept across calls: the second pose gives what a fresh call gives.
  lbs_forward(c, nullptr, sj, sw, T1, kept, nullptr, nullptr, true);  // empty: copies anyway
  ASSERT_EQ(kept.sh, c.sh);
  lbs_forward(c, nullptr, sj, sw, T2, kept, nullptr, nullptr, true);
  EXPECT_EQ(kept.means, fresh.means);
  EXPECT_EQ(kept.quats, fresh.quats);
  EXPECT_EQ(kept.log_scales, fresh.log_scales);
  EXPECT_EQ(kept.opacity_logits, fresh.opacity_logits);
  EXPECT_EQ(kept.sh, fresh.sh);
}

TEST(Lbs, SkinJointOutOfRangeIsAnError) {
  Gaussians c;
  c.resize(3);
  std::mt19937_64 rng(2);
  const auto T = random_transforms(4, rng);
  const std::vector<float> sw(6, 0.5f);
  Gaussians posed;
  for (const int bad : {-1, 4, 1000}) {
    const std::vector<int> sj = {0, 1, 2, bad, 3, 0};
    try {
      lbs_forward(c, nullptr, sj, sw, T, posed);
      ADD_FAILURE() << bad << " accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("skin joint " + std::to_string(bad) + " out of range"),
                std::string::npos)
          << e.what();
    }
  }
}

// Blocks of 8 (AVX2) and of 4 (SSE2) pose alike, bit for bit: a count that leaves a partial block,
// four weights per Gaussian over joints that repeat, back-face culling on.
TEST(Lbs, BothBlockWidthsPoseAlike) {
  std::mt19937_64 rng(4);
  const int n = 37, J = 5, K = 4;
  Gaussians c = random_canonical(n, 0, rng);
  for (float& v : c.quats) v = float(test::randv(1, rng)[0]);  // unnormalised rotations
  std::vector<int> sj(size_t(n) * K);
  std::vector<float> sw(sj.size());
  for (size_t q = 0; q < sj.size(); ++q) {
    sj[q] = int(std::uniform_int_distribution<int>(0, J - 1)(rng));
    sw[q] = float(std::uniform_real_distribution<double>(0, 1)(rng));
  }
  std::vector<float> offsets(3 * size_t(n)), normals(3 * size_t(n));
  for (float& v : offsets) v = 0.01f * float(test::randv(1, rng)[0]);
  for (float& v : normals) v = float(test::randv(1, rng)[0]);
  const auto T = random_transforms(J, rng);
  BackfaceCull cull;
  cull.normals = &normals;
  cull.eye = Eigen::Vector3d(0.1, 0.2, 3.0);
  cull.threshold = 0.2f;
  Gaussians wide, narrow;
  LbsCache cw, cn;
  lbs_forward(c, offsets.data(), sj, sw, T, wide, &cw, &cull);
  const bool was = lbs_allow_avx2(false);
  lbs_forward(c, offsets.data(), sj, sw, T, narrow, &cn, &cull);
  lbs_allow_avx2(was);
  size_t culled = 0;
  for (float o : narrow.opacity_logits) culled += o == kCulledOpacityLogit;
  EXPECT_GT(culled, 0u);
  EXPECT_LT(culled, size_t(n));
  EXPECT_EQ(wide.means, narrow.means);
  EXPECT_EQ(wide.quats, narrow.quats);
  EXPECT_EQ(wide.opacity_logits, narrow.opacity_logits);
  EXPECT_EQ(cw.M, cn.M);
  EXPECT_EQ(cw.qblend, cn.qblend);
}

}  // namespace
}  // namespace ks
