// The lift's step 1 (generate/lift_offsets.hpp): silhouette offsets at the rim, their targets,
// their smoothing over the body.
#include <gtest/gtest.h>

#include <algorithm>
#include <opencv2/imgproc.hpp>

#include "body/parts.hpp"
#include "core/math.hpp"
#include "generate/lift_offsets.hpp"
#include "lift_case.hpp"

namespace ks {

namespace {

Image dilated(const Image& m, int r) {
  Image out = m;
  cv::Mat a(m.height, m.width, CV_32FC1, const_cast<float*>(m.data.data()));
  cv::Mat b(out.height, out.width, CV_32FC1, out.data.data());
  cv::dilate(a, b, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * r + 1, 2 * r + 1)));
  return out;
}

std::vector<lift::RimOffset> rim_of(const test::LiftCase& c, const Image& mask,
                                    const LiftOptions& o) {
  return lift::rim_offsets(c.body.posed.vertices, c.body.posed_normals, c.fit.camera, c.body.render,
                           mask, o);
}

}  // namespace

TEST(LiftOffsets, RimOffsetsStayWithinTheirBounds) {
  const test::LiftCase c(1);
  for (const auto& [lo, hi] : {std::pair{-0.02, 0.12}, std::pair{-0.004, 0.01}}) {
    LiftOptions o = c.options;
    o.min_offset = lo;
    o.max_offset = hi;
    const auto rim = rim_of(c, c.mask, o);
    ASSERT_GT(rim.size(), 20u);
    for (const auto& r : rim) {
      EXPECT_GE(r.offset, lo);
      EXPECT_LE(r.offset, hi);
      ASSERT_GE(r.vertex, 0);
      ASSERT_LT(r.vertex, c.body.vertices());
    }
  }
}

TEST(LiftOffsets, RimOffsetsMeasureTheMasksStandoff) {
  const test::LiftCase c(1);
  // The body's own outline as the mask: offsets of about nothing; grown by 4 pixels: of about
  // 4 pixels at the body's depth.
  const Camera& cam = c.fit.camera;
  const double depth = cam.to_camera(c.body.posed.joints.row(0).transpose()).z();
  const double px = depth / cam.fx;  // metres per pixel at the body
  std::vector<double> same, grown;
  for (const auto& r : rim_of(c, c.body.render.mask, c.options)) same.push_back(r.offset);
  for (const auto& r : rim_of(c, dilated(c.body.render.mask, 4), c.options))
    grown.push_back(r.offset);
  ASSERT_GT(same.size(), 20u);
  ASSERT_GT(grown.size(), 20u);
  EXPECT_LT(std::abs(median(same)), 1.5 * px);
  EXPECT_GT(median(grown), 2.5 * px);
  EXPECT_LT(median(grown), 6.0 * px);
}

TEST(LiftOffsets, TargetsSkipTheTubeAndZeroTheFace) {
  const test::LiftCase c(1);
  const auto rim = rim_of(c, c.mask, c.options);
  const long N = c.body.vertices();
  const lift::OffsetTargets free = lift::offset_targets(rim, {}, c.body, c.fit.camera, c.options);
  ASSERT_EQ(free.targets.size(), free.weights.size());
  size_t rim_targets = 0, face = 0;
  for (size_t t = 0; t < free.targets.size(); ++t) {
    if (free.weights[t] == 1.0) ++rim_targets;
    if (free.weights[t] == c.options.w_face_zero) {
      EXPECT_EQ(free.targets[t].second, 0.0);
      EXPECT_EQ(c.body.person.labels[size_t(free.targets[t].first)], kHeadNeck);
      EXPECT_GT(c.body.rest_normals(free.targets[t].first, 2), c.options.face_min_normal_z);
      ++face;
    }
  }
  EXPECT_EQ(rim_targets, rim.size());
  EXPECT_GT(face, 5u);
  // Everything under a tube: no rim target, a soft zero on every vertex instead.
  LiftOptions o = c.options;
  o.w_under_tube_zero = 0.25;
  const std::vector<uint8_t> all(size_t(N), 1);
  const lift::OffsetTargets tubed = lift::offset_targets(rim, all, c.body, c.fit.camera, o);
  EXPECT_EQ(long(tubed.targets.size()), N + long(face));
  for (size_t t = 0; t < size_t(N); ++t) {
    EXPECT_EQ(tubed.weights[t], 0.25);
    EXPECT_EQ(tubed.targets[t].second, 0.0);
  }
  // The pull on surfaces seen face-on adds targets only when asked for.
  o = c.options;
  o.w_facing_zero = 0.2;
  EXPECT_GT(lift::offset_targets(rim, {}, c.body, c.fit.camera, o).targets.size(),
            free.targets.size() + 100);
}

TEST(LiftOffsets, SmoothOffsetsFitTheTargetsWithinBounds) {
  const test::LiftCase c(1);
  const long N = c.body.vertices();
  const auto& S = c.body.person.stencil;
  // The same value everywhere: the smoothing returns it everywhere.
  lift::OffsetTargets flat;
  for (long i = 0; i < N; ++i) {
    flat.targets.emplace_back(int(i), 0.03);
    flat.weights.push_back(1.0);
  }
  const Eigen::VectorXd x = lift::smooth_offsets(S, *c.fit.model, flat, c.options);
  ASSERT_EQ(x.size(), N);
  EXPECT_LT((x.array() - 0.03).abs().maxCoeff(), 1e-3);
  // Values beyond the bounds are clamped to them.
  for (auto& t : flat.targets) t.second = 0.5;
  LiftOptions o = c.options;
  const Eigen::VectorXd y = lift::smooth_offsets(S, *c.fit.model, flat, o);
  EXPECT_NEAR(y.maxCoeff(), o.max_offset, 1e-12);
  EXPECT_NEAR(y.minCoeff(), o.max_offset, 1e-12);
  // The photo's targets: every offset within [min_offset, max_offset].
  const auto rim = rim_of(c, c.mask, c.options);
  const Eigen::VectorXd z = lift::smooth_offsets(
      S, *c.fit.model, lift::offset_targets(rim, {}, c.body, c.fit.camera, c.options), c.options);
  EXPECT_GE(z.minCoeff(), c.options.min_offset);
  EXPECT_LE(z.maxCoeff(), c.options.max_offset);
  EXPECT_GT(z.maxCoeff(), 0.0);
}

}  // namespace ks
