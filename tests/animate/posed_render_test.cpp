// Posing inside the projection (animate/posed_render.hpp) against posing first: the same image
// bit for bit, with pose correctives, back-face culling, both LBS block widths, both projection
// widths, one and two threads, and a count that leaves partial chunks and blocks.
#include "animate/posed_render.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include <random>

#include "avatar/from_body.hpp"
#include "body/body_model.hpp"
#include "core/error.hpp"

namespace ks {
namespace {

TEST(PosedRender, SameImageAsPosingFirst) {
  const BodyModel& model = default_body_model();
  Eigen::VectorXd betas = Eigen::VectorXd::Zero(std::min(model.num_betas, 2));
  PlainAvatarOptions ao;
  ao.subdivide = 1;
  Avatar a = avatar_from_body(model, betas, ao);
  if (a.posedirs.size() == 0) {  // the default model has none: small made-up ones
    a.posedirs = 0.002f * Eigen::MatrixXf::Random(3 * a.num_gaussians(), 9 * (a.num_joints() - 1));
  }
  ASSERT_GT(a.num_gaussians(), 2048);
  ASSERT_NE(a.num_gaussians() % 8, 0) << "a count that leaves a partial block";
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  BodyParams p;
  p.betas = betas;
  p.global_orient = Eigen::Vector3d(0.1, 2.5, 0.05);  // turned mostly away
  p.body_pose.resize(3 * model.num_body_pose_joints());
  for (int k = 0; k < p.body_pose.size(); ++k) p.body_pose[k] = u(rng);
  p.transl = Eigen::Vector3d(0.05, -0.1, 0.0);
  const Camera cam =
      Camera::look_at({0.0, 0.2, 3.0}, {0, 0, 0}, {0, 1, 0}, 96, 128, 150, 150, 48, 64);
  const std::vector<float> normals = avatar_anchor_normals(a);
  ASSERT_FALSE(normals.empty());
  BackfaceCull cull;
  cull.normals = &normals;
  cull.eye = cam.centre();
  cull.threshold = 0.4f;
  PosedRenderer renderer(a);
  const int saved = omp_get_max_threads();
  const std::vector<const BackfaceCull*> culls = {nullptr, &cull};
  for (const BackfaceCull* c : culls)
    for (const RasterKernel k : {RasterKernel::kBaseline, RasterKernel::kAuto})
      for (const bool wide_lbs : {false, true})
        for (const int threads : {1, 2}) {
          omp_set_num_threads(threads);
          const bool was = lbs_allow_avx2(wide_lbs);
          RasterSettings s;
          s.kernel = k;
          s.image_only = true;
          s.background[1] = 0.5f;
          Gaussians posed;
          pose_avatar(a, p, posed, c);
          RasterResult first, fused;
          rasterize_forward(posed, cam, s, first);
          renderer.render(p, cam, s, fused, c);
          lbs_allow_avx2(was);
          const std::string what =
              std::string(c ? "culled" : "all") + ", kernel " + std::to_string(int(k)) + ", lbs " +
              (wide_lbs ? "wide" : "narrow") + ", " + std::to_string(threads) + " threads";
          EXPECT_EQ(fused.color.data, first.color.data) << what;
          EXPECT_EQ(fused.alpha.data, first.alpha.data) << what;
          EXPECT_EQ(fused.radii, first.radii) << what;
        }
  omp_set_num_threads(saved);
  // The render is not empty and the body is posed (the cull drops some of it).
  RasterSettings s;
  s.image_only = true;
  RasterResult all, culled;
  renderer.render(p, cam, s, all);
  renderer.render(p, cam, s, culled, &cull);
  size_t drawn_all = 0, drawn_culled = 0;
  for (int r : all.radii) drawn_all += r > 0;
  for (int r : culled.radii) drawn_culled += r > 0;
  EXPECT_GT(drawn_all, size_t(a.num_gaussians()) / 2);
  EXPECT_LT(drawn_culled, drawn_all);
}

TEST(PosedRender, SkinOutOfRangeIsAnErrorAtConstruction) {
  const BodyModel& model = default_body_model();
  Avatar a = avatar_from_body(model, Eigen::VectorXd::Zero(std::min(model.num_betas, 2)));
  a.skin_joints[5] = a.num_joints();
  EXPECT_THROW(PosedRenderer{a}, Error);
  a.skin_joints[5] = -1;
  EXPECT_THROW(PosedRenderer{a}, Error);
}

}  // namespace
}  // namespace ks
