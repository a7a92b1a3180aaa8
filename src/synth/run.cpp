#include "synth/run.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "core/fileio.hpp"
#include "core/progress.hpp"
#include "dataset/dataset.hpp"
#include "io/image_io.hpp"
#include "io/video.hpp"
#include "motion/motion.hpp"
#include "perceive/openpose.hpp"
#include "synth/keypoints.hpp"

namespace ks {

using Vec3 = Eigen::Vector3d;

const std::array<SynthTestPose, 8> kSynthTestPoses = {{{"walk", 8},
                                                       {"walk", 24},
                                                       {"wave", 30},
                                                       {"wave", 45},
                                                       {"dance", 8},
                                                       {"dance", 40},
                                                       {"a-t-pose", 18},
                                                       {"a-t-pose", 30}}};

namespace {

nlohmann::json pose_json(const BodyParams& p) {
  auto vec = [](const Eigen::VectorXd& v) {
    return std::vector<double>(v.data(), v.data() + v.size());
  };
  return {{"global_orient", vec(p.global_orient)},
          {"body_pose", vec(p.body_pose)},
          {"transl", vec(p.transl)}};
}

Image mask_image(const MeshRenderOutput& r) {
  return r.mask;
}

// Every `stride`-th vertex (for camera fitting).
Eigen::MatrixXd subsample_rows(const Eigen::MatrixXd& V, int stride) {
  Eigen::MatrixXd out((V.rows() + stride - 1) / stride, 3);
  for (long i = 0, k = 0; i < V.rows(); i += stride, ++k) out.row(k) = V.row(i);
  return out;
}

// `front` carried round the vertical axis through `pivot` (the point it looks at) by
// `azimuth_deg`, at the same distance and height, still looking at the pivot.
Camera orbit_camera(const Camera& front, const Eigen::Vector3d& pivot, double azimuth_deg) {
  if (azimuth_deg == 0) return front;
  const Eigen::Vector3d off = front.centre() - pivot;
  const double a = azimuth_deg * M_PI / 180.0;
  const Eigen::Vector3d eye =
      pivot + Eigen::AngleAxisd(a, Eigen::Vector3d::UnitY()).toRotationMatrix() * off;
  return Camera::look_at(eye, pivot, Eigen::Vector3d::UnitY(), front.width, front.height, front.fx,
                         front.fy, front.cx, front.cy);
}

// The middle of the bounding box of every row of every matrix (what synth_camera looks at).
Eigen::Vector3d box_centre(const std::vector<const Eigen::MatrixXd*>& sets) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e30), hi = Eigen::Vector3d::Constant(-1e30);
  for (const auto* P : sets)
    for (long i = 0; i < P->rows(); ++i) {
      lo = lo.cwiseMin(P->row(i).transpose());
      hi = hi.cwiseMax(P->row(i).transpose());
    }
  return 0.5 * (lo + hi);
}

}  // namespace

void run_synth(const SynthRunConfig& cfg) {
  if (cfg.out_dir.empty()) throw Error("synth: no output directory");
  if (cfg.width < 8 || cfg.height < 8) throw Error("synth: image size must be at least 8x8");
  if (cfg.frames < 1)
    throw Error("synth: the training split needs at least 1 frame, got " +
                std::to_string(cfg.frames));
  if (cfg.camera != "fixed" && cfg.camera != "orbit")
    throw Error("synth: camera \"" + cfg.camera + "\": expected fixed or orbit");
  if (cfg.video && find_ffmpeg().empty())
    throw Error("synth: the training video needs ffmpeg, which was not found on PATH");
  const Motion train_motion = load_motion(cfg.motion, cfg.frames);
  if (train_motion.frames.empty())
    throw Error("synth: the motion \"" + cfg.motion + "\" has no frames");
  std::shared_ptr<const BodyModel> model;
  if (cfg.body_model == "default")
    model = std::shared_ptr<const BodyModel>(&default_body_model(), [](const BodyModel*) {});
  else
    model = std::make_shared<const BodyModel>(load_body_model(cfg.body_model));
  // Datasets resolve a relative model path against their own directory: record it absolute.
  const std::string model_name =
      cfg.body_model == "default"
          ? cfg.body_model
          : std::filesystem::absolute(cfg.body_model).lexically_normal().string();
  const SynthPerson person = make_synth_person(model, model_name, cfg.seed, cfg.options);
  const int W = cfg.width, H = cfg.height;
  const Vec3 white(1, 1, 1);

  StagedDir staged(cfg.out_dir);
  const auto root = staged.staging();
  const int total = 1 + int(train_motion.frames.size()) + int(kSynthTestPoses.size()) * 4;
  Progress progress("synth", total);
  int done = 0;
  auto tick = [&] {
    ++done;
    if (cfg.progress) progress.update(done);
  };

  // The standing pose and the training motion, framed by one fixed front camera.
  const BodyParams stand = standing_pose();
  const PosedPerson stand_posed = pose_synth_person(person, stand);
  std::vector<Eigen::MatrixXd> motion_sub;
  motion_sub.reserve(train_motion.frames.size());
  for (const auto& f : train_motion.frames)
    motion_sub.push_back(subsample_rows(pose_synth_person(person, f).vertices, 5));
  const Eigen::MatrixXd stand_sub = subsample_rows(stand_posed.vertices, 5);
  std::vector<const Eigen::MatrixXd*> framing = {&stand_sub};
  for (const auto& t : motion_sub) framing.push_back(&t);
  const Camera front = synth_camera(framing, 0.0, W, H);

  // Photo, its mask and keypoints, the subject's ground truth.
  {
    BodyParams photo_pose = stand;
    Camera photo_cam = front;
    if (!cfg.photo_pose.empty() || cfg.photo_azimuth != 0) {
      if (!cfg.photo_pose.empty()) {
        const size_t colon = cfg.photo_pose.find(':');
        if (colon == std::string::npos)
          throw Error("synth: --photo-pose must be MOTION:FRAME, got '" + cfg.photo_pose + "'");
        const Motion m = builtin_motion(cfg.photo_pose.substr(0, colon));
        int frame = -1;
        try {
          frame = std::stoi(cfg.photo_pose.substr(colon + 1));
        } catch (const std::exception&) {
        }
        if (frame < 0 || frame >= int(m.frames.size()))
          throw Error("synth: --photo-pose frame out of range (the motion has " +
                      std::to_string(m.frames.size()) + " frames)");
        photo_pose = m.frames[size_t(frame)];
      }
      const Eigen::MatrixXd sub = subsample_rows(pose_synth_person(person, photo_pose).vertices, 3);
      photo_cam = synth_camera({&sub}, cfg.photo_azimuth, W, H);
    }
    const PosedPerson photo_posed = pose_synth_person(person, photo_pose);
    const MeshRenderOutput r = render_synth(person, photo_posed, photo_cam, cfg.supersample, white);
    write_png((root / "photo.png").string(), r.rgb);
    write_png((root / "photo_mask.png").string(), mask_image(r));
    const auto kp = synth_keypoints(person, photo_posed, photo_cam, r);
    PersonKeypoints people;
    for (size_t k = 0; k < kp.size(); ++k) people.body[k] = {kp[k].x(), kp[k].y(), kp[k].z()};
    write_text_atomic((root / "photo_keypoints.json").string(), openpose_json(people).dump(1));
    nlohmann::json subject;
    subject["format"] = "kinesplat-synth-subject";
    subject["version"] = "1.0";
    subject["seed"] = cfg.seed;
    subject["body_model"] = model_name;
    subject["betas"] =
        std::vector<double>(person.betas.data(), person.betas.data() + person.betas.size());
    subject["pose"] = pose_json(synth_params(person, photo_pose));
    subject["camera"] = photo_cam.to_json();
    subject["image"] = "photo.png";
    subject["mask"] = "photo_mask.png";
    subject["keypoints"] = "photo_keypoints.json";
    subject["appearance"] = person.appearance.to_json();
    subject["train"] = {{"motion", cfg.motion},
                        {"camera", cfg.camera},
                        {"frames", train_motion.frames.size()},
                        {"fps", train_motion.fps}};
    subject["mesh"] = {{"vertices", person.rest.rows()},
                       {"faces", person.faces.rows()},
                       {"subdivision_levels", cfg.options.subdivision_levels}};
    write_text_atomic((root / "subject.json").string(), subject.dump(1));
    tick();
  }

  auto make_dataset = [&]() {
    Dataset d;
    d.body_model = model_name;
    d.betas = person.betas;
    return d;
  };
  // Renders one frame into the dataset; returns its image.
  auto add_frame = [&](Dataset& d, const std::filesystem::path& dir, const BodyParams& pose,
                       const PosedPerson& posed, const Camera& cam) {
    const MeshRenderOutput r = render_synth(person, posed, cam, cfg.supersample, white);
    char name[32];
    std::snprintf(name, sizeof(name), "%04zu.png", d.frames.size());
    DatasetFrame f;
    f.image = std::string("images/") + name;
    f.mask = std::string("masks/") + name;
    write_png((dir / f.image).string(), r.rgb);
    write_png((dir / f.mask).string(), mask_image(r));
    f.pose = synth_params(person, pose);
    f.pose.betas.resize(0);
    f.camera = cam;
    d.frames.push_back(std::move(f));
    tick();
    return r.rgb;
  };

  // Training set: the motion from the fixed front camera, or from one orbiting the body at the
  // same distance (azimuth 360 i / N for frame i, looking at the same centre).
  {
    const auto dir = root / "train";
    Dataset d = make_dataset();
    std::unique_ptr<Mp4Writer> video;
    if (cfg.video) {
      std::filesystem::create_directories(dir);
      VideoOptions vo;
      vo.fps = train_motion.fps;
      video = std::make_unique<Mp4Writer>((dir / "video.mp4").string(), W, H, vo);
    }
    const Eigen::Vector3d pivot = box_centre(framing);
    const size_t N = train_motion.frames.size();
    for (size_t i = 0; i < N; ++i) {
      const BodyParams& pose = train_motion.frames[i];
      const Camera cam =
          cfg.camera == "orbit" ? orbit_camera(front, pivot, 360.0 * double(i) / double(N)) : front;
      const Image rgb = add_frame(d, dir, pose, pose_synth_person(person, pose), cam);
      if (video) video->add(rgb);
    }
    d.save(dir.string());
    if (video) video->finish();
  }
  // Test set: 8 novel poses, each from the front, left, right and back.
  {
    const auto dir = root / "test";
    Dataset d = make_dataset();
    for (const auto& tp : kSynthTestPoses) {
      const Motion m = builtin_motion(tp.motion);
      const BodyParams& pose = m.frames.at(size_t(tp.frame));
      const PosedPerson posed = pose_synth_person(person, pose);
      const Eigen::MatrixXd sub = subsample_rows(posed.vertices, 3);
      for (double az : {0.0, 90.0, -90.0, 180.0})
        add_frame(d, dir, pose, posed, synth_camera({&sub}, az, W, H));
    }
    d.save(dir.string());
  }
  staged.commit();
  if (cfg.progress) progress.finish();
}

}  // namespace ks
