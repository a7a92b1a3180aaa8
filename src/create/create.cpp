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

// Where every stage reads and writes, inside DIR.
struct Paths {
  fs::path dir, subject, prior;
  std::string img, mask, kps, fit, poses, raw, refined, avatar;
  std::vector<std::string> videos;  // the turntable first, then one per motion
  Paths(const std::string& out_dir, const std::vector<std::string>& motions)
      : dir(out_dir), subject(dir / "subject"), prior(dir / "prior") {
    img = (subject / "image.png").string();
    mask = (subject / "mask.png").string();
    kps = (subject / "keypoints.json").string();
    fit = (subject / "fit.json").string();
    poses = (prior / "poses.json").string();
    raw = (prior / "dataset" / "dataset.json").string();
    refined = (prior / "refined" / "dataset.json").string();
    avatar = (dir / "avatar.ksavatar").string();
    videos.push_back((dir / "turntable.mp4").string());
    for (const auto& m : motions)
      videos.push_back((dir / (fs::path(m).stem().string() + ".mp4")).string());
  }
};

// One stage of create: what it reads and writes, the settings that change its outputs (a stage
// whose recorded settings differ reruns), and the library call that runs it.
struct Stage {
  std::string name;
  json settings;
  std::vector<std::string> inputs, outputs;
  std::function<void()> run;
};

Stage perceive_stage(const Paths& p, const std::string& photo, const CreateOptions& o) {
  std::vector<std::string> in = {photo};
  if (!o.perceive.keypoints_path.empty()) in.push_back(o.perceive.keypoints_path);
  if (!o.perceive.mask_path.empty()) in.push_back(o.perceive.mask_path);
  return {"perceive",
          {{"photo", abs_path(photo)},
           {"keypoints", abs_path(o.perceive.keypoints_path)},
           {"keypoints_pixel_centre", o.perceive.keypoints_pixel_centre},
           {"mask", abs_path(o.perceive.mask_path)},
           {"max_size", o.perceive.max_size},
           {"face", o.perceive.face}},
          in,
          {p.img, p.mask, p.kps, (p.subject / "perceive.json").string()},
          [&p, &o, photo] {
            const PerceiveReport r = run_perceive(photo, p.subject.string(), o.perceive);
            for (const auto& n : r.notes) std::fprintf(stderr, "perceive: note: %s\n", n.c_str());
            std::printf("perceive: %dx%d, keypoints %s (%d of 25), mask %s, face %s\n", r.width,
                        r.height, r.keypoints_source.c_str(), r.body_keypoints,
                        r.mask_source.c_str(), r.face ? "yes" : "no");
          }};
}

Stage fit_stage(const Paths& p, const CreateOptions& o) {
  return {"fit",
          {{"body", o.fit.body == "default" ? o.fit.body : abs_path(o.fit.body)},
           {"keypoints", to_string(o.fit.fit.keypoints)},
           {"focal", o.fit.fit.focal},
           {"fov", o.fit.fit.fov_degrees},
           {"silhouette", o.fit.fit.use_silhouette}},
          {p.img, p.mask, p.kps},
          {p.fit},
          [&p, &o] {
            const FitResult r = run_fit(p.subject.string(), o.fit);
            std::printf("fit: %s the camera, focal %.1f px\n",
                        r.facing_camera ? "facing" : "turned away from", r.camera.fx);
          }};
}

Stage sample_stage(const Paths& p, const CreateOptions& o) {
  return {"sample",
          {{"frames", o.sample.frames},
           {"motion", o.sample.motion},
           {"driving_body", o.sample.driving_body},
           {"max_frame_side", o.max_frame_side}},
          {p.fit},
          {p.poses},
          [&p, &o] {
            SampleOptions so = o.sample;
            if (o.max_frame_side > 0 && so.width == 0 && so.height == 0) {
              const SubjectFit f = load_fit(p.fit);
              const int side = std::max(f.camera.width, f.camera.height);
              if (side > o.max_frame_side) {
                const double s = double(o.max_frame_side) / side;
                so.width = std::max(8, int(std::lround(f.camera.width * s)));
                so.height = std::max(8, int(std::lround(f.camera.height * s)));
              }
            }
            run_sample(p.subject.string(), p.prior.string(), so);
          }};
}

Stage generate_stage(const Paths& p, const CreateOptions& o) {
  return {"generate",
          {{"generator", to_string(o.generate.generator)},
           {"command", o.generate.command},
           {"frames", abs_path(o.generate.frames_dir)},
           {"supersample", o.generate.supersample},
           {"photo_weight", o.generate.photo_weight}},
          {p.poses, p.img, p.mask, p.fit},
          {p.raw},
          [&p, &o] {
            const GenerateReport r = run_generate(p.prior.string(), p.subject.string(), o.generate);
            if (r.generator == to_string(Generator::kLift))
              std::printf("generate: lift: %.0f%% of the surface seen in the photo; %s\n",
                          100 * r.lift.seen, r.lift.garment.c_str());
            std::printf("generate: %d frames\n", r.frames);
          }};
}

Stage augment_stage(const Paths& p, const CreateOptions& o) {
  return {"augment",
          {{"face_fusion", o.augment.face_fusion},
           {"face_warp", o.augment.face_warp},
           {"restore", o.augment.restore_command}},
          {p.raw},
          {p.refined},
          [&p, &o] {
            const AugmentReport r = run_augment(p.prior.string(), p.subject.string(), o.augment);
            std::printf("augment: %d faces fused, %d restored\n", r.faces_fused, r.restored);
          }};
}

Stage reconstruct_stage(const Paths& p, const CreateOptions& o) {
  const TrainOptions& t = o.reconstruct.train;
  return {"reconstruct",
          {{"iterations", t.iterations},
           {"subdivide", t.subdivide},
           {"scale", t.scale},
           {"seed", t.seed},
           {"density", o.reconstruct.density},
           {"laplacian", int(t.loss.laplacian)}},
          {p.refined},
          {p.avatar},
          [&p, &o] {
            const TrainReport r =
                reconstruct_avatar((p.prior / "refined").string(), p.avatar, o.reconstruct);
            if (!r.garment_summary.empty()) std::printf("%s\n", r.garment_summary.c_str());
            std::printf("reconstruct: %d Gaussians, %d steps, %.1f ms a step\n", r.num_gaussians,
                        r.iterations, r.ms_per_iteration);
          }};
}

Stage videos_stage(const Paths& p, const CreateOptions& o) {
  return {"videos",
          {{"motions", o.motions},
           {"width", o.playback.width},
           {"height", o.playback.height},
           {"camera", o.playback.camera}},
          {p.avatar},
          p.videos,
          [&p, &o] {
            const Avatar av = load_avatar(p.avatar);
            PlaybackOptions po = o.playback;
            po.motion = "turn";
            po.camera = "front";
            render_playback(av, p.videos[0], po);
            for (size_t i = 0; i < o.motions.size(); ++i) {
              po = o.playback;
              po.motion = o.motions[i];
              render_playback(av, p.videos[i + 1], po);
            }
          }};
}

// Everything checked before anything runs.
void check_inputs(const std::string& photo, const std::string& out_dir, const CreateOptions& o) {
  if (photo.empty()) throw Error("create: no photo given");
  if (!fs::exists(photo)) throw Error(photo + ": no such file");
  if (fs::is_directory(photo)) throw Error(photo + ": a directory, expected a photo (PNG or JPEG)");
  for (const auto* p : {&o.perceive.keypoints_path, &o.perceive.mask_path})
    if (!p->empty() && !fs::is_regular_file(*p)) throw Error(*p + ": no such file");
  if (out_dir.empty()) throw Error("create: no output folder given");
  if (fs::exists(out_dir) && !fs::is_directory(out_dir))
    throw Error(out_dir + ": exists and is not a folder");
  if (o.generate.generator == Generator::kCommand && o.generate.command.empty())
    throw Error("create: the command generator needs a command line, and none was given");
  if (o.generate.generator == Generator::kFrames && !fs::is_directory(o.generate.frames_dir))
    throw Error("create: the frames generator needs a folder of frames, got \"" +
                o.generate.frames_dir + "\"");
  if (o.max_frame_side < 0) throw Error("create: max_frame_side must be >= 0");
  if (o.reconstruct.train.iterations < 1) throw Error("create: reconstruct needs >= 1 step");
  if (find_ffmpeg().empty())
    throw Error(
        "create: the videos need ffmpeg, which was not found on PATH (apt-get install "
        "ffmpeg)");
  require_density_name(o.reconstruct.density);
  for (const auto& m : o.motions)
    if (m == "turn") throw Error("create: the turntable is always made; give other motions");
  // The photo is decoded once here, so that an unreadable one is refused before DIR is made.
  (void)load_photo(photo);
}

// Runs the stages in order, skipping those that are up to date, recording each in `record`
// (written to record_path after every change).
void run_stages(const std::vector<Stage>& stages, const CreateOptions& o, json& record,
                const std::string& record_path, std::chrono::steady_clock::time_point t_start,
                CreateReport& rep) {
  const int n = int(stages.size());
  bool upstream_ran = false;
  for (int k = 0; k < n; ++k) {
    const Stage& s = stages[size_t(k)];
    fs::file_time_type newest_in{}, oldest_out{};
    const bool have_in = extreme_mtime(s.inputs, false, newest_in);
    const bool have_out = extreme_mtime(s.outputs, true, oldest_out);
    const json& prev = record["stages"].contains(s.name) ? record["stages"][s.name] : json();
    const bool same_settings = prev.is_object() && prev.value("settings", json()) == s.settings;
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
    record["stages"][s.name] = {{"settings", s.settings}, {"status", "running"}};
    write_json_atomic(record_path, record);
    const auto t0 = std::chrono::steady_clock::now();
    s.run();
    cs.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    upstream_ran = true;
    rep.stages.push_back(cs);
    record["stages"][s.name] = {{"settings", s.settings},
                                {"status", "done"},
                                {"seconds", cs.seconds},
                                {"skipped", false},
                                {"finished", now_iso()}};
    write_json_atomic(record_path, record);
    std::fflush(stdout);
  }
}

}  // namespace

CreateReport run_create(const std::string& photo, const std::string& out_dir,
                        const CreateOptions& options) {
  const auto t_start = std::chrono::steady_clock::now();
  CreateOptions o = options;
  check_inputs(photo, out_dir, o);
  const Paths p(out_dir, o.motions);
  fs::create_directories(p.dir);
  CreateReport rep;
  rep.out_dir = p.dir.string();
  rep.subject_dir = p.subject.string();
  rep.prior_dir = p.prior.string();
  rep.avatar = p.avatar;
  const std::string record_path = (p.dir / "create.json").string();

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

  o.perceive.overlay = true;
  o.fit.overlay = true;
  o.fit.fit.progress = false;
  o.sample.progress = o.generate.progress = o.augment.progress = o.progress;
  o.reconstruct.train.progress = o.playback.progress = o.progress;
  const std::vector<Stage> stages = {perceive_stage(p, photo, o), fit_stage(p, o),
                                     sample_stage(p, o),          generate_stage(p, o),
                                     augment_stage(p, o),         reconstruct_stage(p, o),
                                     videos_stage(p, o)};
  try {
    run_stages(stages, o, record, record_path, t_start, rep);
  } catch (const std::exception& e) {
    record["status"] = "failed";
    record["error"] = e.what();
    record["peak_rss_mb"] = rss_mb(RUSAGE_SELF);
    write_json_atomic(record_path, record);
    throw;
  }
  rep.videos = p.videos;
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
