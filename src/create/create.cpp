#include "create/create.hpp"

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "core/fileio.hpp"
#include "fit/fit_file.hpp"
#include "io/video.hpp"
#include "perceive/photo.hpp"
#include "reconstruct/density_ops.hpp"

namespace ks {

namespace fs = std::filesystem;
using nlohmann::json;

CreateOptions::CreateOptions() {
  // The defaults create runs with where they differ from the single stages' (docs/create.md):
  // a quarter of reconstruct's steps (the lift's frames agree with each other; 400 against 800
  // steps measured no loss on synth seeds 0, 1, 2 and 5), density control on.
  reconstruct.density = "gpdc";
  reconstruct.train.iterations = 400;
}

const std::vector<std::string>& create_stage_names() {
  static const std::vector<std::string> n = {"perceive", "fit",         "sample", "generate",
                                             "augment",  "reconstruct", "videos"};
  return n;
}

namespace {

std::string now_iso() {
  const std::time_t t = std::time(nullptr);
  char b[32];
  std::strftime(b, sizeof b, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
  return b;
}

double rss_mb(int who) {
  rusage u{};
  getrusage(who, &u);
  return u.ru_maxrss / 1024.0;  // kilobytes on Linux
}

std::string abs_path(const std::string& p) {
  return p.empty() ? p : fs::absolute(p).lexically_normal().string();
}

const char* generator_name(Generator g) {
  return g == Generator::kLift ? "lift" : g == Generator::kCommand ? "command" : "frames";
}

// The settings of each stage that change its outputs: a stage whose recorded settings differ from
// these reruns.
json stage_settings(const std::string& stage, const std::string& photo, const CreateOptions& o) {
  if (stage == "perceive")
    return {{"photo", abs_path(photo)},
            {"keypoints", abs_path(o.perceive.keypoints_path)},
            {"keypoints_pixel_centre", o.perceive.keypoints_pixel_centre},
            {"mask", abs_path(o.perceive.mask_path)},
            {"max_size", o.perceive.max_size},
            {"face", o.perceive.face}};
  if (stage == "fit")
    return {{"body", o.fit.body == "default" ? o.fit.body : abs_path(o.fit.body)},
            {"keypoints", o.fit.fit.keypoints == KeypointConvention::kJoints ? "joints" : "coco"},
            {"focal", o.fit.fit.focal},
            {"fov", o.fit.fit.fov_degrees},
            {"silhouette", o.fit.fit.use_silhouette}};
  if (stage == "sample")
    return {{"frames", o.sample.frames},
            {"motion", o.sample.motion},
            {"driving_body", o.sample.driving_body},
            {"max_frame_side", o.max_frame_side}};
  if (stage == "generate")
    return {{"generator", generator_name(o.generate.generator)},
            {"command", o.generate.command},
            {"frames", abs_path(o.generate.frames_dir)},
            {"supersample", o.generate.supersample},
            {"photo_weight", o.generate.photo_weight}};
  if (stage == "augment")
    return {{"face_fusion", o.augment.face_fusion},
            {"face_warp", o.augment.face_warp},
            {"restore", o.augment.restore_command}};
  if (stage == "reconstruct") {
    const TrainOptions& t = o.reconstruct.train;
    return {{"iterations", t.iterations},
            {"subdivide", t.subdivide},
            {"scale", t.scale},
            {"seed", t.seed},
            {"density", o.reconstruct.density},
            {"laplacian", int(t.loss.laplacian)}};
  }
  return {{"motions", o.motions},
          {"width", o.playback.width},
          {"height", o.playback.height},
          {"camera", o.playback.camera}};
}

// Newest modification time among `paths` (all must exist), or the oldest when `oldest`.
bool extreme_mtime(const std::vector<std::string>& paths, bool oldest, fs::file_time_type& t) {
  bool any = false;
  for (const auto& p : paths) {
    std::error_code ec;
    const auto m = fs::last_write_time(p, ec);
    if (ec) return false;
    if (!any || (oldest ? m < t : m > t)) t = m;
    any = true;
  }
  return any;
}

}  // namespace

CreateReport run_create(const std::string& photo, const std::string& out_dir,
                        const CreateOptions& options) {
  const auto t_start = std::chrono::steady_clock::now();
  CreateOptions o = options;
  // ---- Everything checked before anything runs. ----
  if (photo.empty()) throw Error("create: no photo given");
  if (!fs::exists(photo)) throw Error(photo + ": no such file");
  if (fs::is_directory(photo)) throw Error(photo + ": a directory, expected a photo (PNG or JPEG)");
  for (const auto* p : {&o.perceive.keypoints_path, &o.perceive.mask_path})
    if (!p->empty() && !fs::is_regular_file(*p)) throw Error(*p + ": no such file");
  if (out_dir.empty()) throw Error("create: no output folder given");
  if (fs::exists(out_dir) && !fs::is_directory(out_dir))
    throw Error(out_dir + ": exists and is not a folder");
  if (o.generate.generator == Generator::kCommand && o.generate.command.empty())
    throw Error("create: the command generator needs a command (--command)");
  if (o.generate.generator == Generator::kFrames && !fs::is_directory(o.generate.frames_dir))
    throw Error(
        "create: the frames generator needs a folder of frames (--generated-frames), got \"" +
        o.generate.frames_dir + "\"");
  if (o.max_frame_side < 0) throw Error("create: max_frame_side must be >= 0");
  if (o.reconstruct.train.iterations < 1) throw Error("create: reconstruct needs >= 1 step");
  if (find_ffmpeg().empty())
    throw Error(
        "create: the videos need ffmpeg, which was not found on PATH (apt-get install "
        "ffmpeg)");
  if (o.reconstruct.density != "off") {
    const auto& names = density_control_names();
    if (std::find(names.begin(), names.end(), o.reconstruct.density) == names.end())
      throw Error("create: density control \"" + o.reconstruct.density +
                  "\": expected gpdc, vertex, naive or off");
  }
  for (const auto& m : o.motions)
    if (m == "turn") throw Error("create: the turntable is always made; give other motions");

  // The photo is decoded once here, so that an unreadable one is refused before DIR is made.
  (void)load_photo(photo);

  const fs::path dir(out_dir);
  fs::create_directories(dir);
  CreateReport rep;
  rep.out_dir = dir.string();
  rep.subject_dir = (dir / "subject").string();
  rep.prior_dir = (dir / "prior").string();
  rep.avatar = (dir / "avatar.ksavatar").string();
  const fs::path subject(rep.subject_dir), prior(rep.prior_dir);
  const std::string record_path = (dir / "create.json").string();

  json record = json::object();
  if (fs::exists(record_path)) {
    try {
      record = read_json(record_path);
    } catch (const std::exception&) {
      record = json::object();  // unreadable: every stage's settings count as changed
    }
  }
  if (!record.contains("stages") || !record["stages"].is_object())
    record["stages"] = json::object();
  record["photo"] = abs_path(photo);
  record["status"] = "running";
  record.erase("error");
  record["started"] = now_iso();
  write_json_atomic(record_path, record);

  std::vector<std::string> video_paths = {(dir / "turntable.mp4").string()};
  for (const auto& m : o.motions)
    video_paths.push_back((dir / (fs::path(m).stem().string() + ".mp4")).string());

  struct Stage {
    std::string name;
    std::vector<std::string> inputs, outputs;
    std::function<void()> run;
  };
  const std::string img = (subject / "image.png").string(), mask = (subject / "mask.png").string(),
                    kps = (subject / "keypoints.json").string(),
                    fitj = (subject / "fit.json").string(), poses = (prior / "poses.json").string(),
                    raw = (prior / "dataset" / "dataset.json").string(),
                    refined = (prior / "refined" / "dataset.json").string();
  std::vector<std::string> perceive_in = {photo};
  if (!o.perceive.keypoints_path.empty()) perceive_in.push_back(o.perceive.keypoints_path);
  if (!o.perceive.mask_path.empty()) perceive_in.push_back(o.perceive.mask_path);

  o.perceive.overlay = true;
  o.fit.overlay = true;
  o.fit.fit.progress = false;
  o.sample.progress = o.generate.progress = o.augment.progress = o.progress;
  o.reconstruct.train.progress = o.playback.progress = o.progress;

  const std::vector<Stage> stages = {
      {"perceive",
       perceive_in,
       {img, mask, kps, (subject / "perceive.json").string()},
       [&] {
         const PerceiveReport r = run_perceive(photo, subject.string(), o.perceive);
         for (const auto& n : r.notes) std::fprintf(stderr, "perceive: note: %s\n", n.c_str());
         std::printf("perceive: %dx%d, keypoints %s (%d of 25), mask %s, face %s\n", r.width,
                     r.height, r.keypoints_source.c_str(), r.body_keypoints, r.mask_source.c_str(),
                     r.face ? "yes" : "no");
       }},
      {"fit",
       {img, mask, kps},
       {fitj},
       [&] {
         const FitResult r = run_fit(subject.string(), o.fit);
         std::printf("fit: %s the camera, focal %.1f px\n",
                     r.facing_camera ? "facing" : "turned away from", r.camera.fx);
       }},
      {"sample",
       {fitj},
       {poses},
       [&] {
         SampleOptions so = o.sample;
         if (o.max_frame_side > 0 && so.width == 0 && so.height == 0) {
           const SubjectFit f = load_fit(fitj);
           const int side = std::max(f.camera.width, f.camera.height);
           if (side > o.max_frame_side) {
             const double s = double(o.max_frame_side) / side;
             so.width = std::max(8, int(std::lround(f.camera.width * s)));
             so.height = std::max(8, int(std::lround(f.camera.height * s)));
           }
         }
         run_sample(subject.string(), prior.string(), so);
       }},
      {"generate",
       {poses, img, mask, fitj},
       {raw},
       [&] {
         const GenerateReport r = run_generate(prior.string(), subject.string(), o.generate);
         if (r.generator == "lift")
           std::printf("generate: lift: %.0f%% of the surface seen in the photo; %s\n",
                       100 * r.lift.seen, r.lift.garment.c_str());
         std::printf("generate: %d frames\n", r.frames);
       }},
      {"augment",
       {raw},
       {refined},
       [&] {
         const AugmentReport r = run_augment(prior.string(), subject.string(), o.augment);
         std::printf("augment: %d faces fused, %d restored\n", r.faces_fused, r.restored);
       }},
      {"reconstruct",
       {refined},
       {rep.avatar},
       [&] {
         const TrainReport r =
             reconstruct_avatar((prior / "refined").string(), rep.avatar, o.reconstruct);
         if (!r.garment_summary.empty()) std::printf("%s\n", r.garment_summary.c_str());
         std::printf("reconstruct: %d Gaussians, %d steps, %.1f ms a step\n", r.num_gaussians,
                     r.iterations, r.ms_per_iteration);
       }},
      {"videos",
       {rep.avatar},
       video_paths,
       [&] {
         const Avatar av = load_avatar(rep.avatar);
         PlaybackOptions po = o.playback;
         po.motion = "turn";
         po.camera = "front";
         render_playback(av, video_paths[0], po);
         for (size_t i = 0; i < o.motions.size(); ++i) {
           po = o.playback;
           po.motion = o.motions[i];
           render_playback(av, video_paths[i + 1], po);
         }
       }},
  };

  const int n = int(stages.size());
  bool upstream_ran = false;
  try {
    for (int k = 0; k < n; ++k) {
      const Stage& s = stages[size_t(k)];
      const json settings = stage_settings(s.name, photo, o);
      fs::file_time_type newest_in{}, oldest_out{};
      const bool have_in = extreme_mtime(s.inputs, false, newest_in);
      const bool have_out = extreme_mtime(s.outputs, true, oldest_out);
      const json& prev = record["stages"].contains(s.name) ? record["stages"][s.name] : json();
      const bool same_settings = prev.is_object() && prev.value("settings", json()) == settings;
      const bool up_to_date = !o.force && !upstream_ran && have_out && have_in &&
                              oldest_out >= newest_in && same_settings;
      const double elapsed =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
      CreateStage cs;
      cs.name = s.name;
      if (up_to_date) {
        cs.skipped = true;
        std::printf("create [%d/%d %5.0fs] %s: up to date, skipped\n", k + 1, n, elapsed,
                    s.name.c_str());
        rep.stages.push_back(cs);
        record["stages"][s.name]["skipped"] = true;
        continue;
      }
      if (o.progress) std::printf("create [%d/%d %5.0fs] %s\n", k + 1, n, elapsed, s.name.c_str());
      std::fflush(stdout);
      record["stages"][s.name] = {{"settings", settings}, {"status", "running"}};
      write_json_atomic(record_path, record);
      const auto t0 = std::chrono::steady_clock::now();
      s.run();
      cs.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      upstream_ran = true;
      rep.stages.push_back(cs);
      record["stages"][s.name] = {{"settings", settings},
                                  {"status", "done"},
                                  {"seconds", cs.seconds},
                                  {"skipped", false},
                                  {"finished", now_iso()}};
      write_json_atomic(record_path, record);
      std::fflush(stdout);
    }
  } catch (const std::exception& e) {
    record["status"] = "failed";
    record["error"] = e.what();
    record["peak_rss_mb"] = rss_mb(RUSAGE_SELF);
    write_json_atomic(record_path, record);
    throw;
  }
  rep.videos = video_paths;
  rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  rep.peak_rss_mb = rss_mb(RUSAGE_SELF);
  record["status"] = "done";
  record["finished"] = now_iso();
  record["seconds"] = rep.seconds;
  record["peak_rss_mb"] = rep.peak_rss_mb;
  record["outputs"] = {{"subject", rep.subject_dir},
                       {"prior", rep.prior_dir},
                       {"avatar", rep.avatar},
                       {"videos", rep.videos}};
  write_json_atomic(record_path, record);
  return rep;
}

}  // namespace ks
