#include "synth/keypoints.hpp"
#include "synth/person.hpp"
#include "synth/rng.hpp"
#include "synth/run.hpp"

#include <gtest/gtest.h>

#include "perceive/openpose.hpp"

#include "temp_dir.hpp"

#include <filesystem>
#include <nlohmann/json.hpp>

#include "body/parts.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "dataset/dataset.hpp"
#include "io/image_io.hpp"
#include "io/video.hpp"
#include "motion/motion.hpp"

namespace fs = std::filesystem;

namespace ks {

namespace {

std::shared_ptr<const BodyModel> default_model() {
  return std::shared_ptr<const BodyModel>(&default_body_model(), [](const BodyModel*) {});
}

const SynthPerson& person_level1() {
  static const SynthPerson p = [] {
    SynthOptions o;
    o.subdivision_levels = 1;
    return make_synth_person(default_model(), "default", 7, o);
  }();
  return p;
}

}  // namespace

TEST(Synth, RngIsDeterministicAndDistributed) {
  SynthRng a(42), b(42), c(43);
  bool differs = false;
  for (int i = 0; i < 100; ++i) {
    const uint64_t x = a.next();
    EXPECT_EQ(x, b.next());
    differs |= x != c.next();
  }
  EXPECT_TRUE(differs);
  SynthRng r(1);
  double sum = 0, sum2 = 0, umin = 1, umax = 0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    const double u = r.uniform();
    umin = std::min(umin, u);
    umax = std::max(umax, u);
    const double g = r.normal();
    sum += g;
    sum2 += g * g;
  }
  EXPECT_GE(umin, 0.0);
  EXPECT_LT(umax, 1.0);
  EXPECT_NEAR(sum / n, 0.0, 0.03);
  EXPECT_NEAR(sum2 / n, 1.0, 0.05);
  for (int i = 0; i < 1000; ++i) {
    const int k = r.index(7);
    ASSERT_GE(k, 0);
    ASSERT_LT(k, 7);
  }
}

TEST(Synth, PersonIsDeterministicClothedAndSkinned) {
  const SynthPerson& p = person_level1();
  const BodyModel& m = default_body_model();
  ASSERT_EQ(p.rest.rows(), p.colors.rows());
  ASSERT_EQ(long(p.labels.size()), p.rest.rows());
  EXPECT_GT(p.rest.rows(), m.num_vertices());  // subdivided
  EXPECT_GE(p.colors.minCoeff(), 0.0);
  EXPECT_LE(p.colors.maxCoeff(), 1.0);
  for (long i = 0; i < p.skin_weights.rows(); ++i)
    ASSERT_NEAR(p.skin_weights.row(i).sum(), 1.0, 1e-9);
  // Same seed, same person; another seed differs in shape or colours.
  SynthOptions o;
  o.subdivision_levels = 1;
  const SynthPerson q = make_synth_person(default_model(), "default", 7, o);
  EXPECT_EQ((q.rest - p.rest).norm(), 0.0);
  EXPECT_EQ((q.colors - p.colors).norm(), 0.0);
  const SynthPerson r = make_synth_person(default_model(), "default", 8, o);
  EXPECT_GT((r.colors - p.colors).norm() + (r.betas - p.betas).norm(), 0.1);
  // Clothing and hair stand off the body surface: the clothed rest surface lies outside the
  // undisplaced one by up to a few centimetres.
  BodyParams zero;
  zero.betas = p.betas;
  zero.body_pose = Eigen::VectorXd::Zero(69);
  const Eigen::MatrixXd base = p.stencil * body_forward(m, zero).rest_vertices;
  const Eigen::VectorXd d = (p.rest - base).rowwise().norm();
  EXPECT_GT(d.maxCoeff(), 0.01);
  EXPECT_LT(d.maxCoeff(), 0.06);
  // Distinct colour regions: many different colours.
  int distinct = 0;
  std::vector<Eigen::Vector3d> seen;
  for (long i = 0; i < p.colors.rows() && distinct < 12; i += 7) {
    const Eigen::Vector3d c = p.colors.row(i).transpose();
    bool found = false;
    for (const auto& s : seen) found |= (s - c).norm() < 0.05;
    if (!found) {
      seen.push_back(c);
      ++distinct;
    }
  }
  EXPECT_GE(distinct, 6);
  // Zero pose: the posed person is its rest surface; a pose moves it rigidly per part.
  BodyParams rest_pose;
  rest_pose.body_pose = Eigen::VectorXd::Zero(69);
  const PosedPerson pr = pose_synth_person(p, rest_pose);
  EXPECT_LT((pr.vertices - p.rest).cwiseAbs().maxCoeff(), 1e-9);
  BodyParams moved = rest_pose;
  moved.transl = Eigen::Vector3d(0.5, -0.2, 1.0);
  moved.global_orient = Eigen::Vector3d(0, M_PI / 2, 0);
  const PosedPerson pm = pose_synth_person(p, moved);
  // Rotating about the pelvis keeps distances between vertices.
  EXPECT_NEAR((pm.vertices.row(0) - pm.vertices.row(100)).norm(),
              (p.rest.row(0) - p.rest.row(100)).norm(), 1e-9);
}

// A skirt hides the hips and thighs it covers: their faces are dropped, so that no pose can push
// them through the tube; the rest of the body and the skirt itself stay.
TEST(Synth, SkirtHidesTheBodyItCovers) {
  SynthOptions o;
  o.subdivision_levels = 1;
  const long body_faces = 4 * default_body_model().faces.rows();
  bool saw_skirt = false, saw_other = false;
  for (uint64_t seed = 0; seed < 12 && !(saw_skirt && saw_other); ++seed) {
    const SynthPerson p = make_synth_person(default_model(), "default", seed, o);
    const long nbody = p.stencil.rows();
    long nbody_faces = 0, lower_leg_faces = 0, covered_faces = 0;
    double top = -1e9, hem = 1e9;
    for (long v = nbody; v < p.rest.rows(); ++v) {
      top = std::max(top, p.rest(v, 1));
      hem = std::min(hem, p.rest(v, 1));
    }
    auto covered = [&](int v) {
      const int l = p.labels[size_t(v)];
      const double y = p.rest(v, 1);
      return (l == kHips || l == kLeftUpperLeg || l == kRightUpperLeg) && y > hem + 0.04 &&
             y < top - 0.07;
    };
    for (long f = 0; f < p.faces.rows(); ++f) {
      const Eigen::Vector3i t = p.faces.row(f);
      if (t.maxCoeff() >= nbody) continue;
      ++nbody_faces;
      lower_leg_faces += p.labels[size_t(t[0])] == kLeftLowerLeg;
      covered_faces += covered(t[0]) && covered(t[1]) && covered(t[2]);
    }
    EXPECT_GT(lower_leg_faces, 0);
    if (p.appearance.bottom_kind == "skirt") {
      saw_skirt = true;
      ASSERT_GT(p.rest.rows(), nbody);
      EXPECT_EQ(covered_faces, 0) << "seed " << seed;
      EXPECT_LT(nbody_faces, body_faces - 100) << "seed " << seed;
      EXPECT_EQ(p.faces.rows() - nbody_faces, 2 * 2 * 60 * 160);  // the tube, both sides
    } else {
      saw_other = true;
      EXPECT_EQ(p.rest.rows(), nbody);
      EXPECT_EQ(nbody_faces, body_faces) << "seed " << seed;
    }
  }
  EXPECT_TRUE(saw_skirt);
  EXPECT_TRUE(saw_other);
}

TEST(Synth, KeypointsLandOnThePerson) {
  const SynthPerson& p = person_level1();
  const PosedPerson posed = pose_synth_person(p, standing_pose());
  for (double az : {0.0, 90.0, 180.0}) {
    const Camera cam = synth_camera({&posed.vertices}, az, 96, 144);
    const MeshRenderOutput r = render_synth(p, posed, cam, 2);
    // The person fills about 87% of the image height.
    int top = 144, bottom = -1;
    for (int y = 0; y < 144; ++y)
      for (int x = 0; x < 96; ++x)
        if (r.mask.at(x, y, 0) > 0) {
          top = std::min(top, y);
          bottom = std::max(bottom, y);
        }
    EXPECT_NEAR(bottom - top + 1, 0.87 * 144, 4.0) << az;
    const auto kp = synth_keypoints(p, posed, cam, r);
    int visible = 0;
    for (int k = 0; k < kBody25Count; ++k) {
      if (kp[k].z() == 0) {
        EXPECT_EQ(kp[k].x(), 0.0);
        continue;
      }
      ++visible;
      const int x = int(std::floor(kp[k].x())), y = int(std::floor(kp[k].y()));
      ASSERT_TRUE(x >= 0 && y >= 0 && x < 96 && y < 144) << body25_names()[k];
      EXPECT_GT(r.mask.at(x, y, 0), 0.0f) << body25_names()[k] << " az " << az;
    }
    if (az == 0.0) {
      // Front view: every body joint, the face and the feet are visible.
      for (int k : {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 19, 22})
        EXPECT_EQ(kp[k].z(), 1.0) << body25_names()[k];
      // Left/right: the body's right is on the image's left.
      EXPECT_LT(kp[2].x(), kp[5].x());
      EXPECT_LT(kp[15].x(), kp[16].x());
      EXPECT_LT(kp[0].y(), kp[1].y());   // nose above neck
      EXPECT_LT(kp[8].y(), kp[10].y());  // hip above knee
    } else if (az == 180.0) {
      // Back view: the face is hidden, the shoulders are not.
      EXPECT_EQ(kp[0].z(), 0.0);
      EXPECT_EQ(kp[15].z(), 0.0);
      EXPECT_EQ(kp[16].z(), 0.0);
      EXPECT_EQ(kp[2].z(), 1.0);
      EXPECT_GT(kp[2].x(), kp[5].x());
    } else {
      // Left side view: the right eye is hidden behind the head, the left one visible.
      EXPECT_EQ(kp[15].z(), 0.0);
      EXPECT_EQ(kp[16].z(), 1.0);
    }
    EXPECT_GE(visible, 10);
  }
  const auto kps =
      synth_keypoints(p, posed, synth_camera({&posed.vertices}, 0, 48, 72),
                      render_synth(p, posed, synth_camera({&posed.vertices}, 0, 48, 72), 1));
  PersonKeypoints person;  // written by the library's OpenPose writer, as run_synth does
  for (size_t k = 0; k < kps.size(); ++k) person.body[k] = {kps[k].x(), kps[k].y(), kps[k].z()};
  const auto j = openpose_json(person);
  ASSERT_EQ(j["people"][0]["pose_keypoints_2d"].size(), 75u);
  EXPECT_DOUBLE_EQ(j["version"].get<double>(), 1.3);
}

TEST(Synth, TinyRunWritesEverything) {
  const test::TempDir tmp("ks_synth_test");
  const fs::path out = tmp.path() / "run";
  SynthRunConfig cfg;
  cfg.seed = 3;
  cfg.out_dir = out.string();
  cfg.width = 64;
  cfg.height = 96;
  cfg.frames = 4;
  cfg.options.subdivision_levels = 0;
  cfg.progress = false;
  run_synth(cfg);
  for (const char* f : {"photo.png", "photo_mask.png", "photo_keypoints.json", "subject.json",
                        "train/dataset.json", "test/dataset.json"})
    EXPECT_TRUE(fs::is_regular_file(out / f)) << f;
  const Image photo = read_image((out / "photo.png").string());
  EXPECT_EQ(photo.width, 64);
  EXPECT_EQ(photo.height, 96);
  EXPECT_FLOAT_EQ(photo.at(0, 0, 0), 1.0f);  // white background
  const Dataset train = Dataset::load((out / "train").string());
  ASSERT_EQ(train.frames.size(), 4u);
  EXPECT_EQ(train.body_model, "default");
  EXPECT_GT(train.betas.size(), 0);
  // One fixed camera; the poses turn.
  EXPECT_EQ((train.frames[0].camera.R - train.frames[3].camera.R).norm(), 0.0);
  EXPECT_NEAR(train.frames[1].pose.global_orient.y(), M_PI / 2, 1e-9);
  const Image m0 = train.load_mask((out / "train").string(), 0);
  double cover = 0;
  for (float v : m0.data) cover += v;
  EXPECT_GT(cover, 0.05 * 64 * 96);
  const Dataset test = Dataset::load((out / "test").string());
  ASSERT_EQ(test.frames.size(), 32u);
  const nlohmann::json subject = read_json((out / "subject.json").string());
  EXPECT_EQ(subject["betas"].size(), size_t(train.betas.size()));
  EXPECT_NO_THROW(Camera::from_json(subject["camera"]));
  EXPECT_EQ(subject["pose"]["body_pose"].size(), 69u);
  const nlohmann::json kp = read_json((out / "photo_keypoints.json").string());
  EXPECT_EQ(kp["people"][0]["pose_keypoints_2d"].size(), 75u);
  // A failing run (unknown body model) leaves nothing behind.
  const fs::path bad = tmp.path() / "bad";
  cfg.out_dir = bad.string();
  cfg.body_model = tmp / "no_such_model.npz";
  EXPECT_THROW(run_synth(cfg), Error);
  EXPECT_FALSE(fs::exists(bad));
}

// The training split along another motion, seen by an orbiting camera, with its video: the
// frames carry the motion's own poses, the cameras go once round the body at one distance and
// height, and every camera still sees the person.
TEST(Synth, MotionAndOrbitTrainingSplit) {
  const test::TempDir tmp("ks_synth_motion");
  const fs::path out = tmp.path() / "run";
  SynthRunConfig cfg;
  cfg.seed = 4;
  cfg.out_dir = out.string();
  cfg.width = 64;
  cfg.height = 96;
  cfg.frames = 8;
  cfg.motion = "walk";
  cfg.camera = "orbit";
  cfg.video = !find_ffmpeg().empty();
  cfg.options.subdivision_levels = 0;
  cfg.progress = false;
  run_synth(cfg);
  const Dataset train = Dataset::load((out / "train").string());
  ASSERT_EQ(train.frames.size(), 8u);
  const Motion walk = builtin_motion("walk", 8);
  const SynthPerson person = make_synth_person(default_model(), "default", 4, cfg.options);
  const Eigen::Vector3d c0 = train.frames[0].camera.centre();
  for (size_t i = 0; i < 8; ++i) {
    const BodyParams truth = synth_params(person, walk.frames[i]);
    EXPECT_LT((train.frames[i].pose.body_pose - truth.body_pose).norm(), 1e-6) << i;
    EXPECT_LT((train.frames[i].pose.transl - truth.transl).norm(), 1e-6) << i;
    const Eigen::Vector3d c = train.frames[i].camera.centre();
    EXPECT_NEAR(c.y(), c0.y(), 1e-9) << i;  // level, at one height
    const Image m = train.load_mask((out / "train").string(), int(i));
    double cover = 0;
    for (float v : m.data) cover += v;
    EXPECT_GT(cover, 0.03 * 64 * 96) << "frame " << i << " sees the person";
  }
  // A quarter of the way round: the camera on the body's left (+X), as far from the pivot.
  const Eigen::Vector3d c2 = train.frames[2].camera.centre();
  EXPECT_GT(c2.x() - c0.x(), 0.5 * std::abs(c0.z() - c2.z()));
  const nlohmann::json subject = read_json((out / "subject.json").string());
  EXPECT_EQ(subject["train"]["motion"], "walk");
  EXPECT_EQ(subject["train"]["camera"], "orbit");
  if (cfg.video) {
    EXPECT_GT(fs::file_size(out / "train/video.mp4"), 1000u);
  }
  // An unknown motion or camera: an error, nothing written.
  for (const auto& [motion, camera] :
       {std::pair<std::string, std::string>{"jump", "fixed"}, {"walk", "sideways"}}) {
    SynthRunConfig bad = cfg;
    bad.out_dir = (tmp.path() / "bad").string();
    bad.motion = motion;
    bad.camera = camera;
    EXPECT_THROW(run_synth(bad), Error) << motion << " " << camera;
    EXPECT_FALSE(fs::exists(tmp.path() / "bad"));
  }
}

}  // namespace ks
