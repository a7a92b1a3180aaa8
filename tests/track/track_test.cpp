// `track`: the input listing, the motion's sign conventions (a known world motion round-tripped
// through the fit's camera representation, motion.npz and load_motion), both fit passes on a
// clean synth walk (true keypoints and masks: fast and deterministic), bad inputs, and the CLI
// with the real detector on a synth video (skipped when the helper is not installed).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "avatar/avatar.hpp"
#include "avatar/from_body.hpp"
#include "avatar/tiny_avatar.hpp"
#include "body/body_model.hpp"
#include "body/keypoints.hpp"
#include "cli_run.hpp"
#include "core/camera.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "core/math.hpp"
#include "evaluate/fit_metrics.hpp"
#include "fit/fit_body.hpp"
#include "fit/fit_file.hpp"
#include "io/image_io.hpp"
#include "motion/amass.hpp"
#include "motion/motion.hpp"
#include "perceive/openpose.hpp"
#include "synth/run.hpp"
#include "temp_dir.hpp"
#include "track/track.hpp"
#include "track/track_file.hpp"
#include "track/track_input.hpp"

namespace fs = std::filesystem;

namespace ks {

namespace {

std::shared_ptr<const BodyModel> default_model() {
  return std::shared_ptr<const BodyModel>(&default_body_model(), [](const BodyModel*) {});
}

// A synth walk seen by its fixed camera, and per frame a subject folder with the frame, its true
// mask and the true joints' BODY_25 points projected (the convention `joints`).
struct SynthTrack {
  test::TempDir tmp{"track"};
  nlohmann::json dataset;
  std::vector<TrackFrameInput> frames;
  std::vector<SubjectFit> truth;
  SynthTrack(uint64_t seed, const std::string& motion, int n) {
    SynthRunConfig cfg;
    cfg.seed = seed;
    cfg.out_dir = tmp / "synth";
    cfg.width = 256;
    cfg.height = 384;
    cfg.frames = n;
    cfg.motion = motion;
    cfg.camera = "fixed";
    cfg.progress = false;
    run_synth(cfg);
    dataset = read_json(tmp / "synth/train/dataset.json");
    const BodyModel& model = default_body_model();
    const auto src = body25_sources(model, KeypointConvention::kJoints);
    const std::vector<double> b = dataset["betas"].get<std::vector<double>>();
    for (int f = 0; f < n; ++f) {
      const auto& fr = dataset["frames"][size_t(f)];
      SubjectFit t;
      t.model = default_model();
      t.params = BodyParams::from_json(fr["pose"], model);
      t.params.betas = Eigen::Map<const Eigen::VectorXd>(b.data(), Eigen::Index(b.size()));
      t.camera = Camera::from_json(fr["camera"]);
      truth.push_back(t);
      const BodyState st = body_forward(model, t.params);
      const Eigen::MatrixXd P = body25_points(src, st.joints, st.vertices);
      PersonKeypoints person;
      for (int k = 0; k < kBody25Count; ++k) {
        const Eigen::Vector3d c = t.camera.to_camera(P.row(k).transpose());
        Keypoint2D& kp = person.body[size_t(k)];
        kp.x = t.camera.fx * c.x() / c.z() + t.camera.cx;
        kp.y = t.camera.fy * c.y() / c.z() + t.camera.cy;
        kp.conf = 1;
      }
      char name[32];
      std::snprintf(name, sizeof name, "subjects/%04d", f);
      const fs::path dir = tmp.path() / name;
      fs::create_directories(dir);
      fs::copy_file(tmp.path() / "synth/train" / fr["image"].get<std::string>(), dir / "image.png");
      fs::copy_file(tmp.path() / "synth/train" / fr["mask"].get<std::string>(), dir / "mask.png");
      write_openpose((dir / "keypoints.json").string(), person);
      TrackFrameInput in;
      in.subject_dir = dir.string();
      in.source = fr["image"].get<std::string>();
      in.index = f;
      in.time_s = f / builtin_motion(motion, n).fps;  // the synth keeps the motion's duration
      frames.push_back(in);
    }
  }
};

// Options for the clean walk: its true keypoints (the joints' convention), the true focal.
TrackOptions clean_walk_options(const SynthTrack& s) {
  TrackOptions o;
  o.fit.keypoints = KeypointConvention::kJoints;
  o.fit.focal = s.truth[0].camera.fx;
  o.progress = false;
  return o;
}

SubjectFit estimate(const TrackResult& r, size_t f, bool independent) {
  SubjectFit e;
  e.model = default_model();
  const FitResult& fr = independent ? r.frames[f].independent : r.frames[f].fit;
  e.params = fr.params;
  e.camera = fr.camera;
  return e;
}

}  // namespace

TEST(TrackInput, SpreadFramesKeepsEndsAndCount) {
  EXPECT_EQ(spread_frames(5, 0), (std::vector<int>{0, 1, 2, 3, 4}));
  EXPECT_EQ(spread_frames(5, 9), (std::vector<int>{0, 1, 2, 3, 4}));
  EXPECT_EQ(spread_frames(11, 3), (std::vector<int>{0, 5, 10}));
  EXPECT_EQ(spread_frames(10, 4), (std::vector<int>{0, 3, 6, 9}));
  EXPECT_EQ(spread_frames(10, 1), (std::vector<int>{0}));
}

TEST(TrackInput, FolderEveryAndMaxFrames) {
  test::TempDir dir("track_in");
  for (int i = 0; i < 10; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "f%02d.png", 9 - i);  // written out of order
    write_png(dir / name, Image(8, 6, 3));
  }
  write_text_atomic(dir / "notes.txt", "not a frame");
  TrackInputOptions o;
  o.every = 2;
  o.max_frames = 3;
  const TrackInput t = list_track_input({dir.str()}, dir / "decoded", o);
  ASSERT_EQ(t.frames.size(), 3u);
  EXPECT_EQ(t.total, 10);
  EXPECT_EQ(t.frames[0].source, "f00.png");
  EXPECT_EQ(t.frames[1].index, 4);
  EXPECT_EQ(t.frames[2].source, "f08.png");
  EXPECT_DOUBLE_EQ(t.frames[2].time_s, 8 / 30.0);
}

TEST(TrackInput, VideoFramesAndFps) {
  test::TempDir dir("track_vid");
  SynthRunConfig cfg;
  cfg.seed = 1;
  cfg.out_dir = dir / "synth";
  cfg.width = 64;
  cfg.height = 96;
  cfg.frames = 7;
  cfg.motion = "walk";
  cfg.video = true;
  cfg.progress = false;
  run_synth(cfg);
  TrackInputOptions o;
  o.every = 3;
  const TrackInput t = list_track_input({dir / "synth/train/video.mp4"}, dir / "decoded", o);
  EXPECT_TRUE(t.video);
  // The synth plays the walk's one cycle over its 7 frames: ffprobe's rate, not a default.
  const double fps = video_fps(dir / "synth/train/video.mp4");
  EXPECT_GT(fps, 0.5);
  EXPECT_NEAR(t.fps, fps, 1e-9);
  ASSERT_EQ(t.frames.size(), 3u);  // frames 0, 3, 6
  EXPECT_EQ(t.frames[1].index, 3);
  EXPECT_EQ(t.frames[2].index, 6);
  EXPECT_NEAR(t.frames[2].time_s, 6 / fps, 1e-9);
  EXPECT_EQ(read_image(t.frames[0].path).width, 64);
}

// A known world motion, as the fit represents it (the body at the origin, the camera's
// translation carrying the body's), through track_motion, motion.npz and load_motion: the same
// posed joints in the world up to the first frame's place.
TEST(TrackMotion, KnownMotionRoundTripsThroughMotionNpz) {
  test::TempDir dir("track_motion");
  const BodyModel& model = default_body_model();
  const Eigen::Matrix3d R = fit::camera_rotation();
  const Eigen::Vector3d tc(0.1, -0.3, 4.0);  // the fixed camera
  TrackResult tr;
  tr.fps = 12.5;
  tr.betas = Eigen::VectorXd::Zero(10);
  std::vector<BodyParams> world;
  for (int f = 0; f < 4; ++f) {
    BodyParams w;
    w.global_orient = Eigen::Vector3d(0.1 * f, 0.5 - 0.3 * f, 0.05);
    w.body_pose = Eigen::VectorXd::Zero(69);
    w.body_pose[3 * 3 + 0] = 0.2 * f;  // the left knee... any joint
    w.body_pose[3 * 15 + 2] = -0.4;
    w.transl = Eigen::Vector3d(0.3 * f, 0.02 * f, -0.2 * f);
    world.push_back(w);
    TrackFrame fr;
    fr.fit.params = w;
    // The keypoint fit puts the body at the origin (transl zero, the move in the camera's
    // translation); registration moves the body itself: odd frames split the move between both.
    fr.fit.params.transl = (f % 2) ? Eigen::Vector3d(0.5 * w.transl) : Eigen::Vector3d::Zero();
    fr.fit.camera.R = R;
    // X_c = R (X + T) + tc = R (X + transl) + (R (T - transl) + tc)
    fr.fit.camera.t = R * (w.transl - fr.fit.params.transl) + tc;
    tr.frames.push_back(fr);
  }
  save_amass_npz(dir / "motion.npz", track_motion(tr));
  const Motion m = load_motion(dir / "motion.npz");
  ASSERT_EQ(m.frames.size(), 4u);
  EXPECT_NEAR(m.fps, 12.5, 1e-9);
  for (size_t f = 0; f < 4; ++f) {
    BodyParams expect = world[f];
    expect.transl = world[f].transl - world[0].transl;
    const Eigen::MatrixXd a = body_forward(model, expect).joints;
    const Eigen::MatrixXd b = body_forward(model, m.frames[f]).joints;
    EXPECT_LT((a - b).cwiseAbs().maxCoeff(), 1e-9) << "frame " << f;
    // And the same image: the fixed camera sees the played-back body where the fit saw it.
    BodyParams fitted = tr.frames[f].fit.params;
    const Eigen::MatrixXd c = body_forward(model, fitted).joints;
    const Eigen::MatrixXd d = body_forward(model, m.frames[f]).joints;
    const Eigen::Vector3d t0 = tr.frames[0].fit.camera.t + R * tr.frames[0].fit.params.transl;
    for (int j = 0; j < c.rows(); ++j) {
      const Eigen::Vector3d seen_fit = R * c.row(j).transpose() + tr.frames[f].fit.camera.t;
      const Eigen::Vector3d seen_played = R * d.row(j).transpose() + t0;
      EXPECT_LT((seen_fit - seen_played).norm(), 1e-9);
    }
  }
}

// Pass 1 and pass 3 on a clean synth walk: one shape, every frame's pose near the truth.
TEST(TrackFit, SharedShapeAndPosesOnACleanSynthWalk) {
  SynthTrack s(3, "walk", 4);
  const TrackOptions o = clean_walk_options(s);
  const std::string out = s.tmp / "track";
  const TrackResult r = track_subjects(s.frames, out, o);
  ASSERT_EQ(r.frames.size(), 4u);
  EXPECT_EQ(r.betas.size(), 10);
  std::vector<double> mpjpe, pa, mpjpe1;
  for (size_t f = 0; f < r.frames.size(); ++f) {
    EXPECT_EQ((r.frames[f].fit.params.betas - r.betas).norm(), 0.0);
    const FitMetrics m = evaluate_fit(estimate(r, f, false), s.truth[f]);
    const FitMetrics m1 = evaluate_fit(estimate(r, f, true), s.truth[f]);
    mpjpe.push_back(m.mpjpe_mm);
    pa.push_back(m.pa_mpjpe_mm);
    mpjpe1.push_back(m1.mpjpe_mm);
    EXPECT_LT(m.mpjpe_mm, 60.0) << "frame " << f;
    EXPECT_LT(m.pa_mpjpe_mm, 40.0) << "frame " << f;
  }
  std::printf("track synth seed 3 walk: MPJPE median %.1f mm (pass 1 %.1f), PA %.1f mm\n",
              median(mpjpe), median(mpjpe1), median(pa));
  const nlohmann::json j = read_json(out + "/track.json");
  EXPECT_EQ(j["format"], "kinesplat-track");
  // A sequence: pass 3 from pass 1, no pass 2 (TrackOptions::shared_pass off).
  EXPECT_TRUE(j["temporal"]["applied"].get<bool>());
  EXPECT_FALSE(j["shared_pass"].get<bool>());
  EXPECT_FALSE(j["frames"][0].contains("shared"));
  EXPECT_EQ(j["frames"].size(), 4u);
  EXPECT_EQ(j["betas"].size(), 10u);
  EXPECT_NEAR(j["focal"].get<double>(), o.fit.focal, 1e-9);
  const Camera c = Camera::from_json(j["frames"][1]["camera"]);
  EXPECT_LT((c.t - r.frames[1].fit.camera.t).norm(), 1e-12);
  const Motion m = load_motion(out + "/motion.npz");
  EXPECT_EQ(m.frames.size(), 4u);
  EXPECT_NEAR(m.fps, builtin_motion("walk", 4).fps, 1e-6);
}

// Pass 3 with the silhouette terms (--temporal-silhouette) on the same clean walk: the masks are
// in every frame's costs, the poses stay near the truth; as a set of photos, no pass 3.
TEST(TrackFit, TemporalSilhouetteAndPhotoSets) {
  SynthTrack s(3, "walk", 4);
  TrackOptions o = clean_walk_options(s);
  o.temporal.silhouette = true;
  const TrackResult r = track_subjects(s.frames, s.tmp / "sil", o);
  ASSERT_TRUE(r.temporal.applied);
  for (size_t f = 0; f < r.frames.size(); ++f) {
    EXPECT_GT(r.frames[f].fit.costs.count("silhouette_cover"), 0u);
    EXPECT_GT(r.frames[f].fit.costs.count("silhouette_inside"), 0u);
    EXPECT_LT(evaluate_fit(estimate(r, f, false), s.truth[f]).mpjpe_mm, 60.0) << "frame " << f;
  }
  const TrackResult photos = track_subjects(s.frames, s.tmp / "photos", o, false);
  EXPECT_FALSE(photos.temporal.applied);
  for (const TrackFrame& f : photos.frames)
    EXPECT_EQ(f.fit.params.body_pose, f.shared.params.body_pose);
  const nlohmann::json pj = read_json(s.tmp / "photos/track.json");
  EXPECT_FALSE(pj["temporal"]["applied"].get<bool>());
  EXPECT_TRUE(pj["shared_pass"].get<bool>());  // a photo set always has pass 2
  EXPECT_TRUE(pj["frames"][0].contains("shared"));
}

// Pass 4 (--avatar): every frame registered through an avatar's render; track.json keeps the
// keypoint track's pose beside; an avatar of another skeleton is refused.
TEST(TrackFit, RegistersEveryFrameThroughAnAvatar) {
  SynthTrack s(3, "walk", 3);
  TrackOptions o = clean_walk_options(s);
  const std::vector<double> b = s.dataset["betas"].get<std::vector<double>>();
  const Avatar avatar = avatar_from_body(
      default_body_model(), Eigen::Map<const Eigen::VectorXd>(b.data(), Eigen::Index(b.size())));
  o.avatar = s.tmp / "body.ksavatar";
  save_avatar(o.avatar, avatar);
  o.registration.iterations = {10, 5};
  const TrackResult r = track_subjects(s.frames, s.tmp / "reg", o, false);
  const nlohmann::json j = read_json(s.tmp / "reg/track.json");
  ASSERT_EQ(r.frames.size(), 3u);
  for (size_t f = 0; f < r.frames.size(); ++f) {
    const TrackFrame& tf = r.frames[f];
    EXPECT_TRUE(tf.registered);
    EXPECT_EQ(tf.registration.steps, 15);
    EXPECT_LE(tf.registration.cost_after, tf.registration.cost_before);
    EXPECT_EQ(tf.keypoint_params.body_pose, tf.shared.params.body_pose);
    EXPECT_EQ(tf.fit.params.body_pose, tf.registration.params.body_pose);
    const nlohmann::json& reg = j["frames"][f]["registration"];
    EXPECT_EQ(reg["improved"].get<bool>(), tf.registration.improved);
    EXPECT_TRUE(reg.contains("keypoint_params"));
  }
  o.avatar = s.tmp / "tiny.ksavatar";
  save_avatar(o.avatar, test::tiny_avatar());
  EXPECT_THROW(track_subjects(s.frames, s.tmp / "bad", o, false), Error);
  EXPECT_FALSE(fs::exists(s.tmp / "bad"));
}

TEST(TrackFit, BadInputsGiveErrorsAndLeaveNothing) {
  test::TempDir dir("track_bad");
  const std::string out = dir / "out";
  TrackOptions o;
  o.progress = false;
  EXPECT_THROW(run_track({dir / "missing.mp4"}, out, o), Error);
  EXPECT_FALSE(fs::exists(out));
  write_text_atomic(dir / "notes.txt", "hello, not a video\n");
  try {
    run_track({dir / "notes.txt"}, out, o);
    ADD_FAILURE() << "a text file was taken as a video";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("not a video"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(out));
  write_png(dir / "frames/a.png", Image(16, 12, 3));
  write_png(dir / "frames/b.png", Image(16, 14, 3));
  try {
    run_track({dir / "frames"}, out, o);
    ADD_FAILURE() << "frames of two sizes were accepted";
  } catch (const Error& e) {
    const std::string w = e.what();
    EXPECT_NE(w.find("a.png"), std::string::npos) << w;
    EXPECT_NE(w.find("b.png"), std::string::npos) << w;
  }
  EXPECT_FALSE(fs::exists(out));
  EXPECT_THROW(run_track({dir / "frames/a.png", dir / "notes.txt"}, out, o), Error);
  EXPECT_FALSE(fs::exists(out));
  // Nothing left beside the output either (no staging folder).
  for (const auto& e : fs::directory_iterator(dir.path()))
    EXPECT_TRUE(e.path().filename() == "notes.txt" || e.path().filename() == "frames") << e.path();
}

namespace {
bool real_helper_installed(std::string* why) {
  const fs::path helper = fs::path(KS_SOURCE_DIR) / "helpers/perceive";
  *why = "the perceive helper is not installed in " + helper.string() + " (run `make deps`)";
  return fs::exists(helper / "node_modules") && fs::exists(helper / "models/.installed") &&
         std::system("node --version >/dev/null 2>&1") == 0;
}
}  // namespace

// The whole command with the detector on a synth video; blank frames: one clear error, nothing
// written.
TEST(TrackCli, TracksASynthVideoWithTheDetector) {
  std::string why;
  if (!real_helper_installed(&why)) GTEST_SKIP() << why;
  test::TempDir dir("track_cli");
  SynthRunConfig cfg;
  cfg.seed = 2;
  cfg.out_dir = dir / "synth";
  cfg.width = 256;
  cfg.height = 384;
  cfg.frames = 3;
  cfg.motion = "walk";
  cfg.video = true;
  cfg.progress = false;
  run_synth(cfg);
  const std::string out = dir / "track";
  const auto run = test::run_cli("track " + (dir / "synth/train/video.mp4") + " --out " + out);
  ASSERT_EQ(run.status, 0) << run.output;
  EXPECT_NE(run.err.find("track: perceive: frame 3/3"), std::string::npos) << run.err;
  const nlohmann::json j = read_json(out + "/track.json");
  ASSERT_EQ(j["frames"].size(), 3u);
  EXPECT_EQ(j["frames"][2]["index"], 2);
  EXPECT_TRUE(fs::exists(out + "/frames/0002/keypoints.json"));
  EXPECT_TRUE(fs::exists(out + "/frames/0002/mask.png"));
  EXPECT_FALSE(fs::exists(out + "/decoded"));
  EXPECT_EQ(read_image(out + "/frames/0001/fit_overlay.png").width, 256);
  EXPECT_TRUE(fs::exists(out + "/overlay.mp4"));
  EXPECT_EQ(load_motion(out + "/motion.npz").frames.size(), 3u);

  Image blank(128, 192, 3);
  std::fill(blank.data.begin(), blank.data.end(), 0.8f);
  write_png(dir / "blank/a.png", blank);
  write_png(dir / "blank/b.png", blank);
  const auto none = test::run_cli("track " + (dir / "blank") + " --out " + (dir / "t2") + " -q");
  EXPECT_EQ(none.status, 1);
  EXPECT_NE(none.err.find("no person found in any of the 2 frames"), std::string::npos) << none.err;
  EXPECT_NE(none.err.find("a.png"), std::string::npos) << none.err;
  EXPECT_FALSE(fs::exists(dir / "t2"));
}

}  // namespace ks
