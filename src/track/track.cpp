#include "track/track.hpp"

#include "avatar/avatar.hpp"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>

#include "avatar/avatar.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "core/math.hpp"
#include "fit/fit_file.hpp"
#include "fit/overlay.hpp"
#include "io/image_io.hpp"
#include "io/video.hpp"
#include "motion/amass.hpp"
#include "perceive/helper.hpp"
#include "track/track_file.hpp"

namespace fs = std::filesystem;

namespace ks {

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

std::string frame_name(const TrackFrameInput& f) {
  return f.source + " (frame " + std::to_string(f.index) + ")";
}

// The folder may be replaced only when it is empty or an earlier track output.
void check_out_dir(const std::string& out_dir) {
  const fs::path p(out_dir);
  std::error_code ec;
  if (!fs::exists(p, ec)) return;
  if (!fs::is_directory(p, ec))
    throw Error("track: the output folder " + out_dir + " exists and is not a folder");
  if (fs::is_empty(p, ec) || fs::exists(p / "track.json", ec)) return;
  throw Error("track: the output folder " + out_dir +
              " is a non-empty folder that is not a track output; choose a new folder");
}

// The kept frames' rate: the input's over the mean step between the kept frames.
double kept_fps(const std::vector<TrackFrame>& frames, double input_fps) {
  if (frames.size() < 2) return input_fps;
  const double span = frames.back().index - frames.front().index;
  return span > 0 ? input_fps * double(frames.size() - 1) / span : input_fps;
}

void write_outputs(const StagedDir& staged, const TrackResult& r) {
  write_json_atomic(staged.path("track.json"), track_json(r));
  save_amass_npz(staged.path("motion.npz"), track_motion(r));
}

// Each frame's fit on the frame: SUBJECT/fit_overlay.png, and all of them as overlay.mp4.
void write_overlays(const BodyModel& model, const StagedDir& staged, const TrackResult& r,
                    const TrackOptions& o) {
  std::unique_ptr<Mp4Writer> video;
  if (!find_ffmpeg().empty()) {
    VideoOptions vo;
    vo.fps = r.fps;
    video = std::make_unique<Mp4Writer>(staged.path("overlay.mp4"), r.width, r.height, vo);
  }
  for (const TrackFrame& f : r.frames) {
    const fs::path dir(f.subject);
    const FitInput in = load_fit_input(dir.string());
    const Image photo = read_image((dir / "image.png").string(), 3);
    const Image img =
        fit_overlay(photo, model, f.fit.params, f.fit.camera, in.keypoints, o.fit.keypoints);
    write_png((dir / "fit_overlay.png").string(), img);
    if (video) video->add(img);
  }
  if (video) video->finish();
}

}  // namespace

TrackResult fit_track(const BodyModel& model, const std::vector<TrackFrameInput>& frames,
                      const TrackOptions& o, bool sequence) {
  const auto t0 = std::chrono::steady_clock::now();
  TrackResult r;
  r.body_model = o.body;
  // Every frame's input, then one focal for all: the option, else the frames' metadata where
  // they all agree (photos from one camera), else the field of view.
  std::vector<FitInput> all;
  for (const TrackFrameInput& f : frames) {
    all.push_back(load_fit_input(f.subject_dir));
    const FitInput& in = all.back();
    if (r.width == 0) {
      r.width = in.width;
      r.height = in.height;
    } else if (in.width != r.width || in.height != r.height) {
      throw Error("track: " + frame_name(f) + " is " + std::to_string(in.width) + "x" +
                  std::to_string(in.height) + ", the first frame " + std::to_string(r.width) + "x" +
                  std::to_string(r.height));
    }
  }
  FitOptions pass1 = o.fit;
  pass1.progress = false;
  r.focal_from = "field of view";
  if (o.fit.focal > 0) {
    r.focal_from = "option";
  } else if (!all.empty()) {
    const double f0 = all.front().metadata_focal;
    bool agree = f0 > 0;
    for (const FitInput& in : all) agree = agree && std::abs(in.metadata_focal - f0) <= 0.01 * f0;
    if (agree) {
      pass1.focal = f0;
      r.focal_from = "metadata";
    } else {
      pass1.focal = fit_focal(o.fit, r.width, r.height);
    }
  }
  for (FitInput& in : all) in.metadata_focal = 0;  // the one focal above holds for every frame
  r.focal = fit_focal(pass1, r.width, r.height);
  std::vector<FitInput> inputs;
  std::vector<TrackFrameInput> kept;
  // Pass 1: each frame on its own.
  for (size_t i = 0; i < frames.size(); ++i) {
    const TrackFrameInput& f = frames[i];
    FitInput& in = all[i];
    TrackFrame tf;
    tf.index = f.index;
    tf.time_s = f.time_s;
    tf.source = f.source;
    try {
      tf.independent = fit_body(model, in, pass1);
    } catch (const Error& e) {
      r.skipped.push_back(frame_name(f) + ": " + e.what());
      if (o.progress)
        std::fprintf(stderr, "track: fit pass 1: skipped %s\n", r.skipped.back().c_str());
      continue;
    }
    for (int k = 0; k < kBody25Count; ++k)
      if (in.keypoints[size_t(k)].z() > 0) tf.keypoints_used.push_back(body25_names()[size_t(k)]);
    if (o.progress)
      std::fprintf(stderr, "track: fit pass 1: frame %zu/%zu (%s) cost %.4g, %.1f s\n", i + 1,
                   frames.size(), f.source.c_str(), tf.independent.costs["total"],
                   tf.independent.seconds);
    r.frames.push_back(std::move(tf));
    inputs.push_back(std::move(in));
    kept.push_back(f);
  }
  if (r.frames.empty())
    throw Error("track: no frame could be fitted" +
                (r.skipped.empty() ? std::string() : " (" + r.skipped.front() + ")"));

  // The shared shape: per coefficient the median over the frames.
  const int nb = int(r.frames.front().independent.params.betas.size());
  r.betas = Eigen::VectorXd::Zero(nb);
  for (int c = 0; c < nb; ++c) {
    std::vector<double> v;
    for (const TrackFrame& f : r.frames)
      if (c < f.independent.params.betas.size()) v.push_back(f.independent.params.betas[c]);
    r.betas[c] = median(v);
  }

  // Pass 2: every frame again with the shape fixed to the shared one.
  FitOptions pass2 = pass1;
  pass2.initial_betas = r.betas;
  for (auto* stages : {&pass2.schedule.per_start, &pass2.schedule.refine})
    for (FitStage& s : *stages) s.free_betas = false;
  const bool pass3 = sequence && o.temporal.enabled && r.frames.size() >= 3;
  r.shared_pass = !pass3 || o.shared_pass;
  for (size_t i = 0; i < r.frames.size(); ++i) {
    TrackFrame& tf = r.frames[i];
    if (!r.shared_pass) {  // pass 3 starts from pass 1's poses with the shared shape
      tf.shared = tf.independent;
      tf.shared.params.betas = r.betas;
      tf.fit = tf.shared;
      tf.subject = kept[i].subject_dir;
      continue;
    }
    tf.shared = fit_body(model, inputs[i], pass2);
    tf.shared.params.betas = r.betas;
    tf.fit = tf.shared;
    tf.subject = kept[i].subject_dir;
    if (o.progress)
      std::fprintf(
          stderr, "track: fit pass 2 (shared shape): frame %zu/%zu (%s) cost %.4g, %.1f s\n", i + 1,
          r.frames.size(), tf.source.c_str(), tf.shared.costs["total"], tf.shared.seconds);
  }

  // Pass 3 on a sequence: all frames at once with the temporal terms.
  r.sequence = sequence;
  if (pass3) {
    std::vector<double> times;
    std::vector<FitResult> fits;
    for (const TrackFrame& f : r.frames) {
      times.push_back(f.time_s);
      fits.push_back(f.shared);
    }
    TemporalOptions to = o.temporal;
    to.progress = o.progress;
    if (o.progress)
      std::fprintf(stderr, "track: fit pass 3 (temporal): %zu frames\n", r.frames.size());
    r.temporal = solve_temporal(model, inputs, times, r.betas, fits, pass2, to);
    for (size_t i = 0; i < r.frames.size(); ++i) r.frames[i].fit = fits[i];
    for (int i : r.temporal.swapped) r.frames[size_t(i)].swapped = true;
    for (int i : r.temporal.restarted) r.frames[size_t(i)].restarted = true;
    if (o.progress)
      std::fprintf(stderr,
                   "track: fit pass 3: cost %.4g -> %.4g, %zu frames' labels exchanged, %zu "
                   "restarted, %.1f s\n",
                   r.temporal.cost_before, r.temporal.cost_after, r.temporal.swapped.size(),
                   r.temporal.restarted.size(), r.temporal.seconds);
  }
  // Pass 4 with an avatar: each frame registered through its render.
  if (!o.avatar.empty()) {
    const Avatar avatar = load_avatar(o.avatar);
    if (avatar.num_joints() != int(model.parents.size()))
      throw Error("track --avatar: " + o.avatar + " has " + std::to_string(avatar.num_joints()) +
                  " joints, the body model " + std::to_string(model.parents.size()));
    const float background[3] = {1.f, 1.f, 1.f};
    for (size_t i = 0; i < r.frames.size(); ++i) {
      TrackFrame& tf = r.frames[i];
      const std::filesystem::path dir(kept[i].subject_dir);
      const Image image = read_image((dir / "image.png").string(), 3);
      const std::string mask_path = (dir / "mask.png").string();
      const Image mask = std::filesystem::exists(mask_path) ? read_image(mask_path, 1) : Image();
      tf.keypoint_params = tf.fit.params;
      tf.registration = register_pose(avatar, tf.fit.params, tf.fit.camera, image, mask, background,
                                      o.registration);
      const BodyParams& q = tf.registration.params;
      tf.fit.params.global_orient = q.global_orient;
      tf.fit.params.body_pose = q.body_pose;
      tf.fit.params.transl = q.transl;
      tf.registered = true;
      if (o.progress)
        std::fprintf(stderr, "track: register: frame %zu/%zu (%s) cost %.4g -> %.4g, %.1f s\n",
                     i + 1, r.frames.size(), tf.source.c_str(), tf.registration.cost_before,
                     tf.registration.cost_after, tf.registration.seconds);
    }
  }
  r.fit_seconds = seconds_since(t0);
  return r;
}

TrackResult track_subjects(const std::vector<TrackFrameInput>& frames, const std::string& out_dir,
                           const TrackOptions& o, bool sequence) {
  check_out_dir(out_dir);
  if (frames.empty()) throw Error("track: no frames given");
  const BodyModel model = load_body_model(o.body);
  TrackResult r = fit_track(model, frames, o, sequence);
  const double dt = frames.back().time_s - frames.front().time_s;
  const int di = frames.back().index - frames.front().index;
  r.input_fps = di > 0 && dt > 0 ? di / dt : o.input.image_fps;
  r.fps = kept_fps(r.frames, r.input_fps);
  StagedDir staged(out_dir);
  write_outputs(staged, r);
  staged.commit();
  return r;
}

TrackResult run_track(const std::vector<std::string>& inputs, const std::string& out_dir,
                      const TrackOptions& o) {
  check_out_dir(out_dir);
  const BodyModel model = load_body_model(o.body);  // a bad --body fails before any work
  StagedDir staged(out_dir);
  const std::string decoded = staged.path("decoded");
  if (o.progress) std::fprintf(stderr, "track: reading %s\n", inputs.front().c_str());
  const TrackInput in = list_track_input(inputs, decoded, o.input);
  if (o.progress)
    std::fprintf(stderr, "track: %zu frames kept of %s%d (%s, %.4g fps)\n", in.frames.size(),
                 in.video && o.input.every > 1 ? "about " : "", in.total,
                 in.video ? "video" : "images", in.fps);

  // Perceive every frame with one helper kept warm (restarted when it died on a frame).
  const auto tp = std::chrono::steady_clock::now();
  PerceiveOptions po = o.perceive;
  po.overlay = false;
  const std::string helper_dir = po.helper_dir.empty() ? find_perceive_helper() : po.helper_dir;
  HelperOptions ho;
  ho.request_timeout_s = po.helper_timeout_s;
  std::unique_ptr<PerceiveHelper> helper = std::make_unique<PerceiveHelper>(helper_dir, ho);
  std::vector<TrackFrameInput> subjects;
  std::vector<std::string> skipped;
  for (size_t i = 0; i < in.frames.size(); ++i) {
    const InputFrame& f = in.frames[i];
    char name[32];
    std::snprintf(name, sizeof name, "frames/%04zu", i);
    TrackFrameInput s;
    s.subject_dir = staged.path(name);
    s.source = f.source;
    s.index = f.index;
    s.time_s = f.time_s;
    try {
      if (!helper->running()) helper = std::make_unique<PerceiveHelper>(helper_dir, ho);
      const PerceiveReport rep = run_perceive(f.path, s.subject_dir, po, *helper);
      if (o.progress)
        std::fprintf(stderr, "track: perceive: frame %zu/%zu (%s) %d keypoints, %.2f s\n", i + 1,
                     in.frames.size(), f.source.c_str(), rep.body_keypoints, rep.seconds);
      subjects.push_back(s);
    } catch (const Error& e) {
      skipped.push_back(frame_name(s) + ": " + e.what());
      if (o.progress) std::fprintf(stderr, "track: perceive: skipped %s\n", skipped.back().c_str());
    }
  }
  helper.reset();
  const double perceive_s = seconds_since(tp);
  if (subjects.empty()) {
    std::string which;
    for (size_t i = 0; i < skipped.size() && i < 5; ++i) which += "\n  " + skipped[i];
    if (skipped.size() > 5) which += "\n  ... and " + std::to_string(skipped.size() - 5) + " more";
    throw Error("track: no person found in any of the " + std::to_string(in.frames.size()) +
                " frames of " + inputs.front() + ":" + which);
  }
  std::error_code ec;
  fs::remove_all(decoded, ec);

  TrackResult r = fit_track(model, subjects, o, in.sequence);
  r.skipped.insert(r.skipped.begin(), skipped.begin(), skipped.end());
  r.perceive_seconds = perceive_s;
  r.video = in.video;
  r.input_fps = in.fps;
  r.fps = kept_fps(r.frames, in.fps);
  if (o.overlay) {
    if (o.progress) std::fprintf(stderr, "track: overlays\n");
    write_overlays(model, staged, r, o);
  }
  // Subject folders relative to TRACK.
  for (TrackFrame& f : r.frames)
    f.subject = fs::path(f.subject).lexically_relative(staged.staging()).string();
  write_outputs(staged, r);
  staged.commit();
  if (o.progress)
    std::fprintf(
        stderr, "track: %zu frames fitted (%zu skipped); perceive %.1f s, fit %.1f s; wrote %s\n",
        r.frames.size(), r.skipped.size(), r.perceive_seconds, r.fit_seconds, out_dir.c_str());
  return r;
}

}  // namespace ks
