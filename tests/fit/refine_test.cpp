// fit --refine-with (fit/refine.hpp): a subject whose photo is a body avatar's render at a known
// pose, and a fit.json at a perturbed pose; the refinement moves the pose towards the truth, keeps
// the keypoint fit beside it, and refuses bad input without writing anything.
#include "fit/refine.hpp"

#include <gtest/gtest.h>

#include <filesystem>

#include "avatar/from_body.hpp"
#include "avatar/pose.hpp"
#include "body/body_model.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "fit/fit_file.hpp"
#include "io/image_io.hpp"
#include "raster/rasterizer.hpp"
#include "temp_dir.hpp"

namespace ks {
namespace {

namespace fs = std::filesystem;

struct Subject {
  test::TempDir tmp{"ks_refine"};
  std::string dir, avatar_path;
  Avatar avatar;
  BodyParams truth, start;
  Camera camera;
};

void make_subject(Subject& s) {
  const BodyModel& model = default_body_model();
  PlainAvatarOptions ao;
  const Eigen::VectorXd betas = Eigen::VectorXd::Zero(model.num_betas);
  s.avatar = avatar_from_body(model, betas, ao);
  // Colour by side and depth so that the render shows the pose inside the outline too.
  const int K = s.avatar.gaussians.coeffs();
  for (int i = 0; i < s.avatar.num_gaussians(); ++i) {
    const float* x = &s.avatar.gaussians.means[3 * size_t(i)];
    const float c[3] = {x[0] > 0 ? 0.9f : 0.2f, x[1] > 0 ? 0.7f : 0.3f, x[2] > 0.02f ? 0.9f : 0.1f};
    for (int k = 0; k < 3; ++k)
      s.avatar.gaussians.sh[size_t(i) * size_t(K) * 3 + size_t(k)] = (c[k] - 0.5f) / 0.28209479f;
  }
  s.dir = (fs::path(s.tmp.path()) / "subject").string();
  fs::create_directories(s.dir);
  s.avatar_path = (fs::path(s.tmp.path()) / "a.ksavatar").string();
  save_avatar(s.avatar_path, s.avatar);
  s.camera =
      Camera::look_at_fov(Eigen::Vector3d(0, 0.2, 3.2), Eigen::Vector3d(0, 0.2, 0), 192, 256, 50);
  s.truth.betas = betas;
  s.truth.global_orient = Eigen::Vector3d(0, 0.3, 0);
  s.truth.body_pose = Eigen::VectorXd::Zero(69);
  s.truth.body_pose[3 * 15 + 2] = -0.9;
  s.truth.body_pose[3 * 16 + 2] = 0.9;
  RasterSettings rs;
  for (float& b : rs.background) b = 1.f;
  RasterResult rr;
  rasterize_forward(pose_avatar(s.avatar, s.truth), s.camera, rs, rr);
  write_png((fs::path(s.dir) / "image.png").string(), rr.color);
  write_png((fs::path(s.dir) / "mask.png").string(), rr.alpha);
  s.start = s.truth;
  s.start.global_orient[1] += 0.1;
  s.start.transl = Eigen::Vector3d(0.03, -0.02, 0);
  s.start.body_pose[3 * 15 + 2] += 0.25;
  FitResult fr;
  fr.params = s.start;
  fr.camera = s.camera;
  fr.costs["total"] = 1.0;
  save_fit((fs::path(s.dir) / "fit.json").string(), "default", fr);
}

double joint_error(const Avatar& a, const BodyParams& p, const BodyParams& q) {
  return (avatar_posed_joints(a, p) - avatar_posed_joints(a, q)).rowwise().norm().mean();
}

TEST(RefineFit, MovesThePoseTowardsThePhotoAndKeepsTheKeypointFit) {
  Subject s;
  make_subject(s);
  const nlohmann::json original = read_json(s.dir + "/fit.json");
  RegisterOptions o;
  o.iterations = {60, 40};
  const RefineFitResult r = refine_fit(s.dir, s.avatar_path, o);
  EXPECT_TRUE(r.registration.improved);
  EXPECT_EQ(read_json(s.dir + "/fit_keypoints.json"), original);
  const nlohmann::json j = read_json(s.dir + "/fit.json");
  EXPECT_EQ(j.at("refined_with"), s.avatar_path);
  EXPECT_TRUE(j.at("costs").at("registration").at("improved").get<bool>());
  EXPECT_EQ(j.at("costs").at("total"), 1.0);  // the keypoint fit's costs are kept
  const SubjectFit refined = load_fit(s.dir + "/fit.json");
  EXPECT_LT(joint_error(s.avatar, refined.params, s.truth),
            0.5 * joint_error(s.avatar, s.start, s.truth));
  // A second refinement starts from the first's result and keeps the original keypoint fit.
  refine_fit(s.dir, s.avatar_path, o);
  EXPECT_EQ(read_json(s.dir + "/fit_keypoints.json"), original);
}

TEST(RefineFit, RefusesBadInputAndWritesNothing) {
  Subject s;
  make_subject(s);
  // No fit.json.
  fs::rename(s.dir + "/fit.json", s.dir + "/moved.json");
  EXPECT_THROW(refine_fit(s.dir, s.avatar_path), Error);
  fs::rename(s.dir + "/moved.json", s.dir + "/fit.json");
  // A missing avatar, then a camera for another image size.
  EXPECT_THROW(refine_fit(s.dir, s.dir + "/none.ksavatar"), Error);
  nlohmann::json j = read_json(s.dir + "/fit.json");
  j["camera"]["width"] = 100;
  write_json_atomic(s.dir + "/fit.json", j);
  EXPECT_THROW(refine_fit(s.dir, s.avatar_path), Error);
  // A mask of another size.
  j["camera"]["width"] = 192;
  write_json_atomic(s.dir + "/fit.json", j);
  write_png(s.dir + "/mask.png", Image(10, 10, 1, 1.f));
  EXPECT_THROW(refine_fit(s.dir, s.avatar_path), Error);
  EXPECT_FALSE(fs::exists(s.dir + "/fit_keypoints.json"));
  EXPECT_EQ(read_json(s.dir + "/fit.json"), j);
}

}  // namespace
}  // namespace ks
