#include "sample/sample.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <limits>
#include <mutex>

#include "core/error.hpp"
#include "core/fileio.hpp"
#include "core/progress.hpp"
#include "io/image_io.hpp"
#include "io/npz.hpp"
#include "io/video.hpp"
#include "meshrender/meshrender.hpp"
#include "motion/amass.hpp"
#include "sample/driving_body.hpp"

namespace ks {

namespace fs = std::filesystem;

namespace {

Eigen::Matrix3d rot(const Eigen::Vector3d& aa) {
  const double t = aa.norm();
  if (t < 1e-14) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(t, aa / t).toRotationMatrix();
}

Eigen::Vector3d aa_of(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd a(R);
  return a.angle() * a.axis();
}

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

bool is_builtin(const std::string& name) {
  for (const auto& m : builtin_motions())
    if (m.name == name) return true;
  return false;
}

std::string frame_name(int f, const char* ext) {
  char b[32];
  std::snprintf(b, sizeof b, "%04d.%s", f, ext);
  return b;
}

// The condition folders (Champ's guidance names, then ours).
const char* const kFolders[] = {"depth", "normal", "semantic_map", "dwpose",
                                "mask",  "shaded", "keypoints"};

void note(bool on, const std::string& s) {
  if (on) std::fprintf(stderr, "sample: %s\n", s.c_str());
}

}  // namespace

DrivingMotion load_driving_motion(const std::string& name_or_path, int frames) {
  if (frames < 1)
    throw Error("the number of frames must be at least 1, got " + std::to_string(frames));
  DrivingMotion d;
  if (is_builtin(name_or_path)) {
    d.motion = builtin_motion(name_or_path, frames);
    return d;
  }
  if (!ends_with(name_or_path, ".npz")) return {load_motion(name_or_path, frames), std::nullopt};
  if (!fs::exists(name_or_path)) throw Error("motion file " + name_or_path + ": no such file");
  const Motion all = load_amass_npz(name_or_path, 0);
  const int M = int(all.frames.size());
  d.motion.name = all.name;
  if (M <= frames) {
    d.motion = all;
  } else {
    d.motion.fps = frames > 1 ? all.fps * (frames - 1) / double(M - 1) : all.fps;
    for (int i = 0; i < frames; ++i) {
      const int k = frames > 1 ? int(std::lround(double(i) * (M - 1) / (frames - 1))) : 0;
      d.motion.frames.push_back(all.frames[size_t(k)]);
    }
  }
  const NpzFile npz = read_npz(name_or_path);
  if (npz.has("betas")) {
    const NpyArray& b = npz.arrays.at("betas");
    if (!b.is_float() && !b.is_integer()) throw Error(name_or_path + ": \"betas\" must be numbers");
    Eigen::VectorXd v(b.size());
    for (int64_t i = 0; i < b.size(); ++i) {
      v[i] = b.as_double(i);
      if (!std::isfinite(v[i])) throw Error(name_or_path + ": \"betas\" holds a non-finite value");
    }
    d.betas = v;
  }
  return d;
}

void fit_params_to_model(BodyParams& p, const BodyModel& model) {
  adapt_body_pose(p, model.num_body_pose_joints());
  if (model.kind == BodyKind::kSMPL || model.kind == BodyKind::kDefault) {
    p.left_hand_pose.resize(0);
    p.right_hand_pose.resize(0);
  }
  if (model.kind != BodyKind::kSMPLX) {
    p.jaw_pose.setZero();
    p.leye_pose.setZero();
    p.reye_pose.setZero();
    p.expression.resize(0);
  }
  if (p.betas.size() > model.num_betas) p.betas.conservativeResize(model.num_betas);
}

std::vector<BodyParams> compose_motion(const SubjectFit& fit, const Motion& motion, bool in_place) {
  if (motion.frames.empty()) throw Error("motion \"" + motion.name + "\" has no frames");
  const Eigen::Matrix3d Rfit = rot(fit.params.global_orient);
  // Heading of the motion's frame 0 (its forward +Z projected on the ground plane).
  const Eigen::Vector3d f0 = rot(motion.frames[0].global_orient) * Eigen::Vector3d::UnitZ();
  const double yaw0 = std::hypot(f0.x(), f0.z()) > 1e-9 ? std::atan2(f0.x(), f0.z()) : 0.0;
  const Eigen::Matrix3d H = Eigen::AngleAxisd(-yaw0, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Vector3d t0 = motion.frames[0].transl;
  std::vector<BodyParams> out;
  out.reserve(motion.frames.size());
  for (const BodyParams& m : motion.frames) {
    BodyParams p = fit.params;  // betas, expression, jaw / eyes, hands of the fit
    const Eigen::Matrix3d Rm = H * rot(m.global_orient);
    Eigen::Vector3d tm = H * (m.transl - t0);
    if (in_place) tm.x() = tm.z() = 0.0;
    p.global_orient = aa_of(Rfit * Rm);
    p.transl = fit.params.transl + Rfit * tm;
    p.body_pose = m.body_pose;
    if (m.left_hand_pose.size()) p.left_hand_pose = m.left_hand_pose;
    if (m.right_hand_pose.size()) p.right_hand_pose = m.right_hand_pose;
    fit_params_to_model(p, *fit.model);
    out.push_back(std::move(p));
  }
  return out;
}

float encode_depth(double z, double near, double far) {
  if (!(z > 0)) return 0.f;
  const double u = std::clamp((z - near) / std::max(far - near, 1e-9), 0.0, 1.0);
  return float(1.0 - 0.8 * u);
}

double decode_depth(float v, double near, double far) {
  if (!(v > 0)) return 0.0;
  return near + (1.0 - double(v)) / 0.8 * (far - near);
}

ConditionImages render_conditions(const BodyModel& model, const SkeletonSources& sources,
                                  const BodyState& state, const Camera& camera,
                                  const ConditionOptions& opt, const Skeleton2D* override_points) {
  if (model.part_labels.size() != size_t(model.num_vertices()))
    throw Error(std::string("sample: the ") + model.kind_name() +
                " model has no per-vertex part labels");
  MeshRenderInput in;
  in.vertices = &state.vertices;
  in.faces = &model.faces;
  in.labels = &model.part_labels;
  MeshRenderOptions o;
  o.supersample = opt.supersample;
  o.lighting = true;
  o.background = Eigen::Vector3d::Zero();
  o.want_rgb = o.want_mask = o.want_depth = o.want_normal = o.want_labels = true;
  const MeshRenderOutput r = render_mesh(camera, in, o);
  const Eigen::Vector3d black = Eigen::Vector3d::Zero();
  ConditionImages c;
  c.depth = Image(r.width, r.height, 1);
  for (size_t i = 0; i < r.depth.data.size(); ++i)
    c.depth.data[i] = encode_depth(r.depth.data[i], opt.depth_near, opt.depth_far);
  c.normal = normal_to_rgb(r.normal, black);
  c.semantic = labels_to_rgb(r.labels, r.width, r.height, black);
  c.mask = r.mask;
  c.shaded = r.rgb;
  const Skeleton3D pts = skeleton_points(sources, state);
  c.visible = skeleton_visibility(sources, pts, camera, r.depth);
  c.skeleton = override_points ? *override_points : project_skeleton(pts, camera);
  c.dwpose = draw_dwpose(c.skeleton, c.visible, r.width, r.height, opt.skeleton);
  return c;
}

Camera resize_camera(const Camera& cam, int width, int height) {
  if (width <= 0 || height <= 0) throw Error("the image size must be positive");
  if (width == cam.width && height == cam.height) return cam;
  const double a0 = double(cam.width) / cam.height, a1 = double(width) / height;
  if (std::abs(a1 / a0 - 1.0) > 0.01)
    throw Error("size " + std::to_string(width) + "x" + std::to_string(height) +
                " has another aspect ratio than the fit's camera (" + std::to_string(cam.width) +
                "x" + std::to_string(cam.height) + ")");
  Camera c = cam;
  const double sx = double(width) / cam.width, sy = double(height) / cam.height;
  c.fx *= sx;
  c.cx *= sx;
  c.fy *= sy;
  c.cy *= sy;
  c.width = width;
  c.height = height;
  return c;
}

namespace {

// run_sample's inputs, read and checked.
struct SampleInputs {
  SubjectFit fit;
  DrivingMotion dm;
  Camera camera;                  // the fit's, resized to the options' size
  std::vector<BodyParams> poses;  // the motion on the fitted subject
  SkeletonSources sources;        // the subject's skeleton
};

void check_sample_options(const std::string& prior_dir, const SampleOptions& opt) {
  if (opt.frames < 1) throw Error("--frames must be at least 1, got " + std::to_string(opt.frames));
  if (opt.supersample < 1 || opt.supersample > 8)
    throw Error("supersample must lie in 1..8, got " + std::to_string(opt.supersample));
  if (prior_dir.empty()) throw Error("no output folder given");
}

SubjectFit load_subject_fit(const std::string& subject_dir) {
  if (!fs::is_directory(subject_dir)) throw Error(subject_dir + ": not a directory");
  const std::string fit_path = (fs::path(subject_dir) / "fit.json").string();
  if (!fs::exists(fit_path))
    throw Error(fit_path + ": missing (run `kinesplat fit " + subject_dir + "` first)");
  SubjectFit fit = load_fit(fit_path);
  const BodyModel& model = *fit.model;
  if (model.part_labels.size() != size_t(model.num_vertices()))
    throw Error(fit_path + ": the " + std::string(model.kind_name()) +
                " body model has no per-vertex part labels");
  return fit;
}

SampleInputs read_sample_inputs(const std::string& subject_dir, const SampleOptions& opt,
                                const SampleNote& note) {
  SampleInputs in;
  in.fit = load_subject_fit(subject_dir);
  in.dm = load_driving_motion(opt.motion, opt.frames);
  if (int(in.dm.motion.frames.size()) < opt.frames)
    note("the motion has " + std::to_string(in.dm.motion.frames.size()) +
         " frames, fewer than --frames " + std::to_string(opt.frames) + ": using them all");
  in.camera = (opt.width > 0 || opt.height > 0)
                  ? resize_camera(in.fit.camera, opt.width, opt.height)
                  : in.fit.camera;
  in.poses = compose_motion(in.fit, in.dm.motion, opt.in_place);
  in.sources = skeleton_sources(*in.fit.model);
  return in;
}

void check_ffmpeg(const std::string& prior_dir) {
  if (find_ffmpeg().empty())
    throw Error("writing " + (fs::path(prior_dir) / "conditions" / "dwpose.mp4").string() +
                " needs ffmpeg, which was not found on PATH (install it, e.g. `apt-get install "
                "ffmpeg`, or give --no-video)");
}

std::string subject_summary(const std::string& subject_dir, const SampleInputs& in) {
  return "subject " + subject_dir + " (" + in.fit.model->kind_name() + " body), camera " +
         std::to_string(in.camera.width) + "x" + std::to_string(in.camera.height) + ", motion \"" +
         in.dm.motion.name + "\": " + std::to_string(in.poses.size()) + " poses at " +
         std::to_string(in.dm.motion.fps).substr(0, 5) + " fps";
}

constexpr double kMinDepthMargin = 0.01;    // metres of camera z
constexpr double kDepthMarginShare = 0.02;  // of the sequence's depth range
constexpr double kMinDepthNear = 1e-3;      // metres

// The depth encoding's range: camera z of every vertex over the sequence, with a margin.
ConditionOptions condition_options(const SampleInputs& in, int supersample) {
  double zmin = std::numeric_limits<double>::infinity(), zmax = -zmin;
  for (const BodyParams& pose : in.poses) {
    const BodyState s = body_forward(*in.fit.model, pose);
    for (long i = 0; i < s.vertices.rows(); ++i) {
      const double z = in.camera.to_camera(s.vertices.row(i).transpose()).z();
      if (z > 0) {
        zmin = std::min(zmin, z);
        zmax = std::max(zmax, z);
      }
    }
  }
  if (!(zmin <= zmax)) throw Error("sample: the body is behind the fit's camera in every pose");
  const double margin = std::max(kMinDepthMargin, kDepthMarginShare * (zmax - zmin));
  ConditionOptions copt;
  copt.supersample = supersample;
  copt.depth_near = std::max(kMinDepthNear, zmin - margin);
  copt.depth_far = zmax + margin;
  return copt;
}

// The driving body and its alignment to the subject (both or neither).
struct Driving {
  const DrivingBody* body = nullptr;
  const PoseAlignment* alignment = nullptr;
};

void write_condition_images(const fs::path& dir, int f, const ConditionImages& c) {
  const std::string png = frame_name(f, "png");
  write_png((dir / "depth" / png).string(), c.depth);
  write_png((dir / "normal" / png).string(), c.normal);
  write_png((dir / "semantic_map" / png).string(), c.semantic);
  write_png((dir / "dwpose" / png).string(), c.dwpose);
  write_png((dir / "mask" / png).string(), c.mask);
  write_png((dir / "shaded" / png).string(), c.shaded);
  write_text_atomic((dir / "keypoints" / frame_name(f, "json")).string(),
                    skeleton_openpose_json(c.skeleton, c.visible).dump());
}

// Frame f's conditions into dir's folders; its alignment error (none without a driving body).
AlignmentError write_frame(const fs::path& dir, int f, const SampleInputs& in,
                           const ConditionOptions& copt, const Driving& driving) {
  const BodyParams& pose = in.poses[size_t(f)];
  const BodyState s = body_forward(*in.fit.model, pose);
  std::optional<Skeleton2D> aligned;
  AlignmentError err;
  if (driving.alignment)
    aligned =
        aligned_skeleton(*driving.body, *driving.alignment, pose, in.sources, s, in.camera, err);
  const ConditionImages c = render_conditions(*in.fit.model, in.sources, s, in.camera, copt,
                                              aligned ? &*aligned : nullptr);
  write_condition_images(dir, f, c);
  return err;
}

// Every frame's conditions into dir's folders, frames in parallel; the alignment error summed.
AlignmentError write_frames(const fs::path& dir, const SampleInputs& in,
                            const ConditionOptions& copt, const Driving& driving, bool talk) {
  const int N = int(in.poses.size());
  Progress prog("sample", N);
  std::mutex mu;
  std::exception_ptr error;
  std::atomic<int> done{0};
  AlignmentError total;
#pragma omp parallel for schedule(dynamic, 1)
  for (int f = 0; f < N; ++f) {
    {
      std::lock_guard<std::mutex> lock(mu);
      if (error) continue;
    }
    try {
      const AlignmentError err = write_frame(dir, f, in, copt, driving);
      std::lock_guard<std::mutex> lock(mu);
      total.add(err);
      if (talk) prog.update(++done);
    } catch (...) {
      std::lock_guard<std::mutex> lock(mu);
      if (!error) error = std::current_exception();
    }
  }
  if (error) std::rethrow_exception(error);
  if (talk) prog.finish();
  return total;
}

void write_dwpose_video(const fs::path& dir, int frames, double fps) {
  std::vector<std::string> pngs;
  for (int f = 0; f < frames; ++f) pngs.push_back((dir / "dwpose" / frame_name(f, "png")).string());
  VideoOptions vo;
  vo.fps = fps;
  write_mp4_from_pngs((dir / "dwpose.mp4").string(), pngs, vo);
}

// The part labels' colours in semantic_map/ (0-255), by part name.
nlohmann::json semantic_colors() {
  std::vector<int> labels(kNumParts);
  for (int i = 0; i < kNumParts; ++i) labels[size_t(i)] = i;
  const Image pal = labels_to_rgb(labels, kNumParts, 1, Eigen::Vector3d::Zero());
  nlohmann::json parts;
  for (int i = 0; i < kNumParts; ++i)
    parts[std::string(kPartNames[size_t(i)])] = {int(std::lround(pal.at(i, 0, 0) * 255)),
                                                 int(std::lround(pal.at(i, 0, 1) * 255)),
                                                 int(std::lround(pal.at(i, 0, 2) * 255))};
  return parts;
}

// poses.json's "alignment"; says the mean distances.
nlohmann::json alignment_json(const Driving& driving, const AlignmentError& err,
                              const SampleNote& note) {
  if (!driving.alignment) return nullptr;
  const Eigen::VectorXd& betas = driving.body->betas;
  nlohmann::json aj = driving.alignment->to_json();
  aj["driving_body"] = driving.body->name;
  aj["driving_betas"] = std::vector<double>(betas.data(), betas.data() + betas.size());
  aj["mean_px_from_subject"] = {{"unaligned", err.unaligned / std::max(1L, err.points)},
                                {"aligned", err.aligned / std::max(1L, err.points)}};
  char b[160];
  std::snprintf(b, sizeof b,
                "aligned skeleton %.2f px from the subject's own on average (unaligned %.2f)",
                err.aligned / std::max(1L, err.points), err.unaligned / std::max(1L, err.points));
  note(b);
  return aj;
}

// poses.json's "conditions".
nlohmann::json conditions_json(const SampleInputs& in, const ConditionOptions& copt,
                               const SampleOptions& opt, const Driving& driving,
                               const AlignmentError& err, const SampleNote& note) {
  nlohmann::json cj;
  cj["folder"] = "conditions";
  cj["size"] = {in.camera.width, in.camera.height};
  cj["frames"] = int(in.poses.size());
  cj["supersample"] = opt.supersample;
  cj["depth"] = {{"near", copt.depth_near},
                 {"far", copt.depth_far},
                 {"encoding", "v = 1 - 0.8 (z - near) / (far - near), background 0"}};
  cj["semantic_colors"] = semantic_colors();
  cj["skeleton"] = "coco18";
  cj["video"] = opt.video ? nlohmann::json("conditions/dwpose.mp4") : nlohmann::json(nullptr);
  cj["in_place"] = opt.in_place;
  cj["alignment"] = alignment_json(driving, err, note);
  return cj;
}

PoseSequence pose_sequence(const std::string& subject_dir, const SampleInputs& in) {
  PoseSequence seq;
  seq.body_model = in.fit.body_model;
  seq.model = in.fit.model;
  seq.betas = in.fit.params.betas;
  seq.fps = in.dm.motion.fps;
  seq.motion = in.dm.motion.name;
  seq.subject = fs::absolute(subject_dir).lexically_normal().string();
  for (const BodyParams& p : in.poses) seq.frames.push_back({p, in.camera});
  return seq;
}

// PRIOR/conditions/ (complete or not at all), then PRIOR/poses.json; a PRIOR folder this run
// made goes again when anything fails.
PoseSequence write_prior(const std::string& subject_dir, const std::string& prior_dir,
                         const SampleInputs& in, const ConditionOptions& copt,
                         const Driving& driving, const SampleOptions& opt, const SampleNote& note) {
  const fs::path prior(prior_dir);
  const bool prior_existed = fs::exists(prior);
  try {
    StagedDir staged((prior / "conditions").string());
    for (const char* sub : kFolders) fs::create_directories(staged.staging() / sub);
    const AlignmentError err = write_frames(staged.staging(), in, copt, driving, opt.progress);
    if (opt.video) {
      note("encoding conditions/dwpose.mp4");
      write_dwpose_video(staged.staging(), int(in.poses.size()), in.dm.motion.fps);
    }
    PoseSequence seq = pose_sequence(subject_dir, in);
    seq.conditions = conditions_json(in, copt, opt, driving, err, note);
    std::error_code ec;
    fs::remove(prior / "poses.json", ec);  // never an old poses.json beside new conditions
    staged.commit();
    save_poses((prior / "poses.json").string(), seq);
    return seq;
  } catch (...) {
    std::error_code ec;
    if (!prior_existed) fs::remove_all(prior, ec);
    throw;
  }
}

}  // namespace

PoseSequence run_sample(const std::string& subject_dir, const std::string& prior_dir,
                        const SampleOptions& opt) {
  const SampleNote say = [talk = opt.progress](const std::string& s) { note(talk, s); };
  // ---- Everything is checked before anything is written.
  check_sample_options(prior_dir, opt);
  const SampleInputs in = read_sample_inputs(subject_dir, opt, say);
  const std::optional<DrivingBody> driving_body =
      choose_driving_body(opt.driving_body, in.fit, in.dm.betas, say);
  if (opt.video) check_ffmpeg(prior_dir);
  say(subject_summary(subject_dir, in));

  // ---- Depth range over the sequence, and the alignment of the driving body (SVAD).
  const ConditionOptions copt = condition_options(in, opt.supersample);
  std::optional<PoseAlignment> alignment;
  if (driving_body) {
    alignment =
        align_driving_body(*driving_body, *in.fit.model, in.sources, in.poses[0], in.camera);
    say("pose alignment (SVAD) of the driving body " + driving_body->name + ": " +
        alignment_scales_text(*alignment));
  }

  // ---- Render and write, frames in parallel; then poses.json.
  const Driving driving{driving_body ? &*driving_body : nullptr, alignment ? &*alignment : nullptr};
  return write_prior(subject_dir, prior_dir, in, copt, driving, opt, say);
}

}  // namespace ks
