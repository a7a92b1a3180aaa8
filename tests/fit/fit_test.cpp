// The fit: its templated body against body_forward, its derivatives against finite differences,
// the silhouette pieces, fit.json, and whole fits of a rendered synth person.
#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "body/keypoints.hpp"
#include "cli_run.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "evaluate/fit_metrics.hpp"
#include "evaluate/pose_metrics.hpp"
#include "fit/fit.hpp"
#include "fit/fit_body.hpp"
#include "fit/fit_file.hpp"
#include "fit/keypoint_calibration.hpp"
#include "fit/silhouette.hpp"
#include "io/image_io.hpp"
#include "synth/run.hpp"
#include "temp_dir.hpp"

namespace ks {

namespace fs = std::filesystem;

namespace {

BodyParams random_params(const BodyModel& m, std::mt19937& rng, double spread) {
  std::normal_distribution<double> n(0.0, spread);
  BodyParams p;
  p.global_orient = Eigen::Vector3d(n(rng), n(rng), n(rng));
  p.body_pose = Eigen::VectorXd(3 * m.num_body_pose_joints());
  for (long i = 0; i < p.body_pose.size(); ++i) p.body_pose(i) = n(rng);
  p.betas = Eigen::VectorXd(std::min(10, m.num_betas));
  for (long i = 0; i < p.betas.size(); ++i) p.betas(i) = 2 * n(rng);
  return p;
}

// A synth person's photo as a subject directory (true keypoints and mask), small and quick.
struct SynthSubject {
  test::TempDir tmp{"fit"};
  std::string subject, truth;
  SynthSubject(uint64_t seed, const std::string& pose = "", double azimuth = 0) {
    SynthRunConfig cfg;
    cfg.seed = seed;
    cfg.out_dir = tmp / "synth";
    cfg.width = 256;
    cfg.height = 384;
    cfg.frames = 1;
    cfg.photo_pose = pose;
    cfg.photo_azimuth = azimuth;
    cfg.progress = false;
    run_synth(cfg);
    subject = tmp / "subject";
    fs::create_directories(subject);
    fs::copy_file(tmp / "synth/photo.png", subject + "/image.png");
    fs::copy_file(tmp / "synth/photo_mask.png", subject + "/mask.png");
    fs::copy_file(tmp / "synth/photo_keypoints.json", subject + "/keypoints.json");
    truth = tmp / "synth/subject.json";
  }
};

}  // namespace

TEST(BodyKeypoints, DefaultModelSourcesAreWhereTheyBelong) {
  const BodyModel& m = default_body_model();
  const auto src = body25_sources(m);
  const Eigen::MatrixXd J = m.J_regressor * m.v_template;
  const Eigen::MatrixXd P = body25_points(src, J, m.v_template);
  using namespace body25;
  EXPECT_GT(P(kNose, 2), J(15, 2));     // nose in front of the head joint
  EXPECT_GT(P(kNose, 1), J(12, 1));     // above the neck
  EXPECT_LT(P(kREye, 0), P(kNose, 0));  // the right eye on the body's right (-x)
  EXPECT_GT(P(kLEye, 0), P(kNose, 0));
  EXPECT_LT(P(kREar, 0), P(kREye, 0));  // ears outside the eyes
  EXPECT_GT(P(kLEar, 0), P(kLEye, 0));
  EXPECT_GT(P(kLBigToe, 2), P(kLHeel, 2));  // toes in front of heels
  EXPECT_LT(P(kLBigToe, 1), J(7, 1));       // below the ankle
  EXPECT_NEAR(P(kMidHip, 0), 0.0, 1e-9);    // mid-hip on the midline
  for (int k = 0; k < kBody25Count; ++k) EXPECT_EQ(body25_mirror(body25_mirror(k)), k);
  EXPECT_EQ(body25_mirror(kLWrist), kRWrist);
}

TEST(BodyKeypoints, CocoConventionOffsetsTurnWithTheirBone) {
  const BodyModel& m = default_body_model();
  const auto joints = body25_sources(m, KeypointConvention::kJoints);
  const auto coco = body25_sources(m, KeypointConvention::kCoco);
  BodyParams p;
  p.body_pose = Eigen::VectorXd::Zero(69);
  BodyState st = body_forward(m, p);
  Eigen::MatrixXd A = body25_points(joints, st.joints, st.vertices, &st.transforms);
  Eigen::MatrixXd B = body25_points(coco, st.joints, st.vertices, &st.transforms);
  using namespace body25;
  EXPECT_GT(B(kLShoulder, 1) - A(kLShoulder, 1), 0.03);  // on top of the shoulder
  EXPECT_NEAR(B(kLShoulder, 0) - A(kLShoulder, 0), -(B(kRShoulder, 0) - A(kRShoulder, 0)), 1e-12);
  EXPECT_GT(B(kLWrist, 0) - A(kLWrist, 0), 0.03);        // further down the arm (+x in the T-pose)
  EXPECT_EQ((B.row(kNose) - A.row(kNose)).norm(), 0.0);  // vertex keypoints do not move
  // Raise the left arm 90 degrees about z: the wrist's offset turns with the forearm's bone.
  p.body_pose.segment<3>(3 * (18 - 1)) = Eigen::Vector3d(0, 0, M_PI / 2);  // left elbow
  st = body_forward(m, p);
  A = body25_points(joints, st.joints, st.vertices, &st.transforms);
  B = body25_points(coco, st.joints, st.vertices, &st.transforms);
  EXPECT_GT(B(kLWrist, 1) - A(kLWrist, 1), 0.03);  // now upwards
  // Without the transforms, offsets are left out.
  EXPECT_EQ((body25_points(coco, st.joints, st.vertices) - A).norm(), 0.0);
}

TEST(KeypointCalibration, RecoversKnownOffsets) {
  const BodyModel& m = default_body_model();
  const auto coco = body25_sources(m, KeypointConvention::kCoco);
  std::mt19937 rng(11);
  std::vector<CalibrationSample> samples;
  for (int i = 0; i < 12; ++i) {
    CalibrationSample s;
    s.truth.model = std::shared_ptr<const BodyModel>(&m, [](const BodyModel*) {});
    s.truth.params = random_params(m, rng, 0.25);
    s.truth.params.global_orient = Eigen::Vector3d(0, (i % 4) * 0.6 - 0.9, 0);
    s.truth.camera = fit_camera(FitOptions{}, 512, 768, Eigen::Vector3d(0, 0.2, 3.2));
    const BodyState st = body_forward(m, s.truth.params);
    const Eigen::MatrixXd P = body25_points(coco, st.joints, st.vertices, &st.transforms);
    for (int k = 0; k < kBody25Count; ++k) {
      const Eigen::Vector2d uv = s.truth.camera.project(P.row(k).transpose());
      s.detected[size_t(k)] = Eigen::Vector3d(uv.x(), uv.y(), 1.0);
    }
    samples.push_back(s);
  }
  const KeypointCalibration c = calibrate_keypoints(samples);
  for (int k : {body25::kLShoulder, body25::kRWrist, body25::kLHip, body25::kRKnee}) {
    EXPECT_LT((c.offset[size_t(k)] - coco[size_t(k)].offset).norm(), 0.004) << body25_names()[k];
    EXPECT_LT(c.after_px[size_t(k)], 0.5 * c.before_px[size_t(k)]) << body25_names()[k];
  }
}

TEST(FitBody, ForwardMatchesBodyForward) {
  const BodyModel& m = default_body_model();
  const fit::BodyData d = fit::make_body_data(m, 10, 7);
  std::mt19937 rng(3);
  for (int trial = 0; trial < 3; ++trial) {
    const BodyParams p = random_params(m, rng, 0.4);
    const Eigen::VectorXd x = fit::pack(d.layout, p, Eigen::Vector3d(0.1, -0.2, 3.0));
    std::vector<Eigen::Vector3d> J, V;
    fit::forward<double>(d, x.data(), J, &V);
    const BodyState st = body_forward(m, p);
    for (int j = 0; j < m.num_joints(); ++j)
      EXPECT_LT((J[size_t(j)] - st.joints.row(j).transpose()).norm(), 1e-9) << "joint " << j;
    // The default model has at most 4 skin weights per vertex: the subset's vertices are exact.
    for (size_t i = 0; i < d.vertex_ids.size(); ++i)
      ASSERT_LT((V[i] - st.vertices.row(d.vertex_ids[i]).transpose()).norm(), 1e-9) << i;
    const BodyParams back = fit::unpack_params(d.layout, x);
    EXPECT_LT((back.body_pose - p.body_pose).norm(), 1e-12);
    EXPECT_LT((fit::unpack_cam(d.layout, x) - Eigen::Vector3d(0.1, -0.2, 3.0)).norm(), 1e-12);
  }
}

TEST(FitBody, JetDerivativesMatchFiniteDifferences) {
  const BodyModel& m = default_body_model();
  const fit::BodyData d = fit::make_body_data(m, 10, 97);
  std::mt19937 rng(5);
  const Eigen::VectorXd x = fit::pack(d.layout, random_params(m, rng, 0.3), {0, 0, 3});
  using Jet = ceres::Jet<double, fit::kMaxParams>;
  const int P = d.layout.size;
  std::vector<Jet> xj(static_cast<size_t>(P));
  for (int i = 0; i < P; ++i) xj[size_t(i)] = Jet(x(i), i);
  std::vector<Eigen::Matrix<Jet, 3, 1>> J, V;
  fit::forward<Jet>(d, xj.data(), J, &V);
  const double h = 1e-6;
  double worst = 0;
  for (int i = 0; i < P; i += 3) {  // every third parameter
    Eigen::VectorXd xp = x, xm = x;
    xp(i) += h;
    xm(i) -= h;
    std::vector<Eigen::Vector3d> Jp, Jm, Vp, Vm;
    fit::forward<double>(d, xp.data(), Jp, &Vp);
    fit::forward<double>(d, xm.data(), Jm, &Vm);
    for (size_t j = 0; j < J.size(); ++j)
      for (int k = 0; k < 3; ++k) {
        const double fd = (Jp[j](k) - Jm[j](k)) / (2 * h);
        worst = std::max(worst, std::abs(fd - J[j](k).v[i]));
      }
    for (size_t v = 0; v < V.size(); ++v)
      for (int k = 0; k < 3; ++k) {
        const double fd = (Vp[v](k) - Vm[v](k)) / (2 * h);
        worst = std::max(worst, std::abs(fd - V[v](k).v[i]));
      }
  }
  EXPECT_LT(worst, 1e-6);
}

TEST(FitSilhouette, DistanceFieldValuesAndGradient) {
  Image mask(40, 30, 1, 0.f);
  for (int y = 10; y < 20; ++y)
    for (int x = 10; x < 25; ++x) mask.at(x, y, 0) = 1.f;
  const fit::DistanceField df = fit::outside_distance(mask);
  double du, dv;
  EXPECT_NEAR(df.sample(15.5, 15.5, &du, &dv), 0.0, 1e-9);  // inside
  EXPECT_NEAR(df.sample(30.5, 15.5, &du, &dv), 6.0, 1e-4);  // 6 px right of the last column
  EXPECT_NEAR(du, 1.0, 1e-4);
  // Outside the image: the border value plus the distance beyond it.
  EXPECT_NEAR(df.sample(43.5, 15.5, nullptr, nullptr), 15.0 + 4.0, 1e-3);
  // Gradient against finite differences at generic points inside the image and beyond each
  // border (there the clamped axis contributes the distance beyond the border alone).
  const double h = 1e-4;
  for (const auto& [u, v] : std::vector<std::pair<double, double>>{
           {28.3, 23.7}, {-4.2, 13.3}, {47.1, 23.7}, {28.3, -6.6}, {33.3, 35.2}, {-3.1, 34.4}}) {
    df.sample(u, v, &du, &dv);
    EXPECT_NEAR(
        du,
        (df.sample(u + h, v, nullptr, nullptr) - df.sample(u - h, v, nullptr, nullptr)) / (2 * h),
        1e-3)
        << u << ", " << v;
    EXPECT_NEAR(
        dv,
        (df.sample(u, v + h, nullptr, nullptr) - df.sample(u, v - h, nullptr, nullptr)) / (2 * h),
        1e-3)
        << u << ", " << v;
  }
  const auto pts = fit::outline_samples(mask, 2.0, 1000);
  EXPECT_GE(pts.size(), 20u);
  for (const auto& p : pts) {
    const bool on_x = p.x() == 10.5 || p.x() == 24.5, on_y = p.y() == 10.5 || p.y() == 19.5;
    EXPECT_TRUE(on_x || on_y) << p.transpose();
  }
}

TEST(PoseMetrics, ProcrustesAndIoU) {
  Eigen::MatrixXd A(5, 3);
  A << 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0, 3, 1, 1, 1;
  const Eigen::Matrix3d R = axis_angle_to_matrix<double>(Eigen::Vector3d(0.3, -0.2, 0.5));
  Eigen::MatrixXd B = (1.7 * A * R.transpose()).rowwise() + Eigen::RowVector3d(4, 5, 6);
  EXPECT_NEAR(pa_mpjpe(A, B), 0.0, 1e-9);
  EXPECT_GT(mpjpe(A, B), 0.5);
  Eigen::MatrixXd C = A.rowwise() + Eigen::RowVector3d(1, 2, 3);
  EXPECT_NEAR(mpjpe(C, A), 0.0, 1e-12);
  C(4, 0) += 0.5;  // one joint 0.5 off among 5
  EXPECT_NEAR(mpjpe(C, A), 0.1, 1e-12);
  Image a(10, 10, 1, 0.f), b(10, 10, 1, 0.f);
  for (int y = 0; y < 10; ++y)
    for (int x = 0; x < 4; ++x) a.at(x, y, 0) = 1.f;
  for (int y = 0; y < 10; ++y)
    for (int x = 2; x < 6; ++x) b.at(x, y, 0) = 1.f;
  EXPECT_NEAR(mask_iou(a, b), 20.0 / 60.0, 1e-12);
}

TEST(FitFile, RoundTripAndMalformed) {
  test::TempDir tmp("fitfile");
  FitResult r;
  std::mt19937 rng(1);
  r.params = random_params(default_body_model(), rng, 0.2);
  r.camera = fit_camera(FitOptions{}, 300, 400, Eigen::Vector3d(0.1, 0.2, 3.0));
  r.costs = {{"keypoints", 1.5}};
  save_fit(tmp / "fit.json", "default", r);
  const SubjectFit f = load_fit(tmp / "fit.json");
  EXPECT_EQ(f.body_model, "default");
  EXPECT_LT((f.params.body_pose - r.params.body_pose).norm(), 1e-12);
  EXPECT_LT((f.params.betas - r.params.betas).norm(), 1e-12);
  EXPECT_LT((f.camera.t - r.camera.t).norm(), 1e-12);
  EXPECT_EQ(f.camera.width, 300);
  EXPECT_DOUBLE_EQ(f.costs.at("keypoints").get<double>(), 1.5);

  auto bad = [&](const std::string& text, const std::string& expect) {
    write_text_atomic(tmp / "bad.json", text);
    try {
      load_fit(tmp / "bad.json");
      ADD_FAILURE() << "accepted " << text;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(expect), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("bad.json"), std::string::npos) << e.what();
    }
  };
  bad("{", "bad.json");
  bad("[]", "not a JSON object");
  bad(R"({"camera": {}})", "params");
  nlohmann::json j = read_json(tmp / "fit.json");
  j["params"]["body_pose"] = std::vector<double>(5, 0.0);
  bad(j.dump(), "body_pose");
  j = read_json(tmp / "fit.json");
  j.erase("camera");
  bad(j.dump(), "camera");
  j = read_json(tmp / "fit.json");
  j["body_model"] = "no_such_model.npz";
  bad(j.dump(), "no_such_model.npz");
}

// Every present keypoint at its own index with its own three values, absent ones zero (a build
// for AVX-512 once shifted them by one coordinate).
TEST(Fit, KeypointsAsTheFitReadsThem) {
  PersonKeypoints person;
  for (int k = 0; k < kBody25Count; ++k)
    if (k % 3 != 1) person.body[size_t(k)] = {10.0 * k + 1, 10.0 * k + 2, 0.5 + 0.01 * k};
  const auto kp = fit_keypoints(person);
  for (int k = 0; k < kBody25Count; ++k) {
    const Eigen::Vector3d want = k % 3 != 1
                                     ? Eigen::Vector3d(10.0 * k + 1, 10.0 * k + 2, 0.5 + 0.01 * k)
                                     : Eigen::Vector3d::Zero();
    EXPECT_EQ(kp[size_t(k)], want) << "keypoint " << k;
  }
}

TEST(Fit, StandingSynthPersonFromTrueKeypointsAndMask) {
  SynthSubject s(4);
  const FitInput in = load_fit_input(s.subject);
  FitOptions o;
  o.keypoints = KeypointConvention::kJoints;  // the synth's true keypoints are its joints
  const FitResult r = fit_body(default_body_model(), in, o);
  save_fit(s.tmp / "fit.json", "default", r);
  const FitMetrics m = evaluate_fit(load_fit(s.tmp / "fit.json"), load_fit(s.truth));
  EXPECT_LT(m.pa_mpjpe_mm, 25.0);
  EXPECT_GT(m.silhouette_iou, 0.88);
  // The shape's error: zero against itself, some millimetres from a fit.
  EXPECT_GT(m.rest_vertex_error_mm, 0.0);
  EXPECT_LT(m.rest_vertex_error_mm, 60.0);
  EXPECT_NEAR(evaluate_fit(load_fit(s.truth), load_fit(s.truth)).rest_vertex_error_mm, 0.0, 1e-9);
  EXPECT_TRUE(r.facing_camera);
  for (const char* term : {"keypoints", "silhouette_inside", "silhouette_cover", "pose_prior"})
    EXPECT_TRUE(r.costs.count(term)) << term;
}

TEST(Fit, TurnedAwayPersonIsFoundTurnedAway) {
  SynthSubject s(6, "", 180.0);
  FitOptions o;
  o.keypoints = KeypointConvention::kJoints;
  const FitResult r = fit_body(default_body_model(), load_fit_input(s.subject), o);
  EXPECT_FALSE(r.facing_camera);
  save_fit(s.tmp / "fit.json", "default", r);
  const FitMetrics m = evaluate_fit(load_fit(s.tmp / "fit.json"), load_fit(s.truth));
  EXPECT_LT(m.pa_mpjpe_mm, 40.0);
}

// The focal perceive found in the photo's EXIF (perceive.json's image.focal_px) is the fit's
// camera unless --focal says otherwise; a malformed one is an error naming the file.
TEST(Fit, MetadataFocalFromPerceiveJson) {
  SynthSubject s(4);
  write_json_atomic(s.subject + "/perceive.json",
                    {{"format", "kinesplat-perceive"}, {"image", {{"focal_px", 700.0}}}});
  const FitInput in = load_fit_input(s.subject);
  EXPECT_DOUBLE_EQ(in.metadata_focal, 700.0);
  FitOptions o;
  o.keypoints = KeypointConvention::kJoints;
  std::string from;
  EXPECT_DOUBLE_EQ(fit_focal(o, in, &from), 700.0);
  EXPECT_EQ(from, "metadata");
  EXPECT_DOUBLE_EQ(fit_body(default_body_model(), in, o).camera.fx, 700.0);
  o.focal = 500;
  EXPECT_DOUBLE_EQ(fit_focal(o, in, &from), 500.0);
  EXPECT_EQ(from, "option");
  FitInput none = in;
  none.metadata_focal = 0;
  o.focal = 0;
  EXPECT_DOUBLE_EQ(fit_focal(o, none, &from), fit_focal(o, in.width, in.height));
  EXPECT_EQ(from, "field of view");
  for (const nlohmann::json& bad : {nlohmann::json("wide"), nlohmann::json(-3.0)}) {
    write_json_atomic(s.subject + "/perceive.json", {{"image", {{"focal_px", bad}}}});
    try {
      load_fit_input(s.subject);
      ADD_FAILURE() << "focal_px " << bad.dump() << " was accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("focal_px"), std::string::npos) << e.what();
    }
  }
}

TEST(Fit, RefusesWithoutATorso) {
  FitInput in;
  in.width = 100;
  in.height = 200;
  in.keypoints[body25::kNose] = Eigen::Vector3d(50, 20, 1);
  EXPECT_THROW(fit_body(default_body_model(), in), Error);
  in.mask = Image(50, 50, 1);
  EXPECT_THROW(fit_body(default_body_model(), in), Error);
}

TEST(FitCli, WritesFitAndOverlayAndEvaluates) {
  SynthSubject s(2);
  const auto run = test::run_cli("fit " + s.subject + " --overlay -q --keypoints joints");
  ASSERT_EQ(run.status, 0) << run.output;
  EXPECT_TRUE(fs::exists(s.subject + "/fit.json"));
  const Image ov = read_image(s.subject + "/fit_overlay.png");
  EXPECT_EQ(ov.width, 256);
  const auto ev = test::run_cli("evaluate-fit " + s.subject + "/fit.json " + s.truth + " --out " +
                                (s.tmp / "m.json") + " --renders " + (s.tmp / "r"));
  ASSERT_EQ(ev.status, 0) << ev.output;
  const nlohmann::json m = read_json(s.tmp / "m.json");
  EXPECT_LT(m.at("pa_mpjpe_mm").get<double>(), 30.0);
  for (const char* f : {"front.png", "side.png", "image.png"})
    EXPECT_TRUE(fs::exists(s.tmp / ("r/" + std::string(f)))) << f;
}

TEST(FitCli, BadInputsAreClearErrorsWithNothingWritten) {
  test::TempDir tmp("fitcli");
  auto r = test::run_cli("fit " + (tmp / "missing"));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("not a directory"), std::string::npos) << r.err;
  fs::create_directories(tmp / "s");
  r = test::run_cli("fit " + (tmp / "s"));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("image.png"), std::string::npos) << r.err;
  write_png(tmp / "s/image.png", Image(64, 96, 3, 0.5f));
  write_png(tmp / "s/mask.png", Image(32, 32, 1, 1.f));
  write_text_atomic(tmp / "s/keypoints.json", R"({"people":[{"pose_keypoints_2d":[1,2,3]}]})");
  r = test::run_cli("fit " + (tmp / "s"));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("mask.png"), std::string::npos) << r.err;
  fs::remove(tmp / "s/mask.png");
  r = test::run_cli("fit " + (tmp / "s"));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("BODY_25 has 75"), std::string::npos) << r.err;
  nlohmann::json kp;  // every keypoint absent
  kp["people"] = {{{"pose_keypoints_2d", std::vector<double>(75, 0.0)}}};
  write_json_atomic(tmp / "s/keypoints.json", kp);
  r = test::run_cli("fit " + (tmp / "s"));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("no person has a keypoint"), std::string::npos) << r.err;
  std::vector<double> nose_only(75, 0.0);
  nose_only[0] = 30, nose_only[1] = 10, nose_only[2] = 0.9;
  kp["people"] = {{{"pose_keypoints_2d", nose_only}}};
  write_json_atomic(tmp / "s/keypoints.json", kp);
  r = test::run_cli("fit " + (tmp / "s"));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("torso"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(tmp / "s/fit.json"));
  r = test::run_cli("fit " + (tmp / "s") + " --fov 0");
  EXPECT_EQ(r.status, 1);
}

}  // namespace ks
