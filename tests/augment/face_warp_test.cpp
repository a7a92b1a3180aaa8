// augment/face_warp: the photo carried onto a frame through the body's surface. A body painted
// with a pattern fixed to its surface, photographed facing the camera and then turned: the warp
// of the photo must reproduce the turned render wherever it says it is valid.
#include "augment/face_warp.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "body/body_model.hpp"
#include "core/error.hpp"
#include "meshrender/meshrender.hpp"

namespace ks {
namespace {

struct Scene {
  const BodyModel& model = default_body_model();
  Eigen::MatrixXd colours;
  Camera cam;
  Scene() {
    const Eigen::MatrixXd& T = model.v_template;
    colours.resize(T.rows(), 3);
    for (long i = 0; i < T.rows(); ++i)
      for (int k = 0; k < 3; ++k)
        colours(i, k) = 0.5 + 0.4 * std::sin(25.0 * T(i, 0) + 18.0 * T(i, 1) + 2.0 * k);
    const Eigen::Vector3d head = body_forward(model, params(0)).joints.row(15).transpose();
    cam = Camera::look_at(head + Eigen::Vector3d(0, 0, 0.8), head, Eigen::Vector3d::UnitY(), 128,
                          128, 220, 220, 64, 64);
  }
  BodyParams params(double yaw) const {
    BodyParams p;
    p.body_pose = Eigen::VectorXd::Zero(3 * model.num_body_pose_joints());
    p.global_orient = Eigen::Vector3d(0, yaw, 0);
    return p;
  }
  Eigen::MatrixXd vertices(double yaw) const { return body_forward(model, params(yaw)).vertices; }
  MeshRenderOutput render(const Eigen::MatrixXd& V) const {
    MeshRenderInput in;
    in.vertices = &V;
    in.faces = &model.faces;
    in.colors = &colours;
    MeshRenderOptions o;
    o.cull_backfaces = true;
    return render_mesh(cam, in, o);
  }
};

// Mean absolute difference over the valid pixels, and how many there are.
std::pair<double, int> error_where_valid(const Image& a, const Image& b, const Image& valid) {
  double e = 0;
  int n = 0;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x)
      if (valid.at(x, y, 0) > 0.5f) {
        for (int c = 0; c < 3; ++c) e += std::abs(a.at(x, y, c) - b.at(x, y, c));
        ++n;
      }
  return {n ? e / (3 * n) : 1.0, n};
}

TEST(FaceWarp, SamePoseGivesThePhotoBack) {
  const Scene s;
  const Eigen::MatrixXd V = s.vertices(0);
  const MeshRenderOutput photo = s.render(V);
  const Eigen::MatrixXd seen = photo_surface(V, s.model.faces, s.cam, photo.mask);
  Image src, valid;
  warp_photo_through_body(photo.rgb, seen, V, s.model.faces, s.cam, src, valid);
  const auto [err, n] = error_where_valid(src, photo.rgb, valid);
  EXPECT_GT(n, 2000);
  EXPECT_LT(err, 0.01);
}

TEST(FaceWarp, TurnedHeadMatchesTheTurnedRender) {
  const Scene s;
  const Eigen::MatrixXd V0 = s.vertices(0), V1 = s.vertices(0.6);  // 34 degrees about the vertical
  const MeshRenderOutput photo = s.render(V0), truth = s.render(V1);
  const Eigen::MatrixXd seen = photo_surface(V0, s.model.faces, s.cam, photo.mask);
  Image src, valid;
  warp_photo_through_body(photo.rgb, seen, V1, s.model.faces, s.cam, src, valid);
  const auto [err, n] = error_where_valid(src, truth.rgb, valid);
  EXPECT_GT(n, 1500);
  EXPECT_LT(err, 0.01);
  // Valid only on the body, and the photo itself (not warped) is far off there: the pattern moved.
  for (int y = 0; y < 128; ++y)
    for (int x = 0; x < 128; ++x)
      if (valid.at(x, y, 0) > 0.5f) {
        ASSERT_GT(truth.mask.at(x, y, 0), 0.5f);
      }
  EXPECT_GT(error_where_valid(photo.rgb, truth.rgb, valid).first, 4 * err);
}

TEST(FaceWarp, WhatThePhotoDoesNotSeeIsNotValid) {
  const Scene s;
  // The back of the head (turned 180 degrees) is nowhere in the photo.
  const Eigen::MatrixXd V0 = s.vertices(0), V1 = s.vertices(M_PI);
  const MeshRenderOutput photo = s.render(V0);
  const Eigen::MatrixXd seen = photo_surface(V0, s.model.faces, s.cam, photo.mask);
  Image src, valid;
  warp_photo_through_body(photo.rgb, seen, V1, s.model.faces, s.cam, src, valid);
  EXPECT_LT(error_where_valid(src, src, valid).second, 50);
}

TEST(FaceWarp, MismatchedInputsAreRefused) {
  const Scene s;
  const Eigen::MatrixXd V = s.vertices(0);
  EXPECT_THROW(photo_surface(V, s.model.faces, s.cam, Image(10, 10, 1)), Error);
  Image src, valid;
  EXPECT_THROW(warp_photo_through_body(Image(128, 128, 3), Eigen::MatrixXd::Zero(3, 3), V,
                                       s.model.faces, s.cam, src, valid),
               Error);
}

}  // namespace
}  // namespace ks
