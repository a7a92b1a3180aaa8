#include "generate/generate.hpp"

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>

#include "core/error.hpp"
#include "core/fileio.hpp"
#include "core/names.hpp"
#include "core/process.hpp"
#include "core/progress.hpp"
#include "dataset/dataset.hpp"
#include "io/image_io.hpp"
#include "perceive/perceive.hpp"
#include "synth/person.hpp"

namespace ks {

namespace fs = std::filesystem;

namespace {

std::string frame_name(size_t i) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%04zu.png", i);
  return buf;
}

// Frame 0: the photo composited on the background with its mask.
DatasetFrame photo_frame(const fs::path& root, const Image& photo, const Image& mask,
                         const SubjectFit& fit, const GenerateOptions& o) {
  Image img(photo.width, photo.height, 3);
  for (int y = 0; y < photo.height; ++y)
    for (int x = 0; x < photo.width; ++x) {
      const float a = std::clamp(mask.at(x, y, 0), 0.f, 1.f);
      for (int c = 0; c < 3; ++c)
        img.at(x, y, c) = a * photo.at(x, y, c) + (1 - a) * float(o.background(c));
    }
  DatasetFrame f;
  f.image = "images/" + frame_name(0);
  f.mask = "masks/" + frame_name(0);
  write_png((root / f.image).string(), img);
  write_png((root / f.mask).string(), mask);
  f.pose = fit.params;
  f.pose.betas.resize(0);
  f.camera = fit.camera;
  f.weight = o.photo_weight;
  return f;
}

struct Subject {
  Image photo, mask;
  SubjectFit fit;
};

Subject load_subject(const std::string& subject_dir) {
  const fs::path dir(subject_dir);
  if (!fs::is_directory(dir)) throw Error(subject_dir + ": not a directory");
  Subject s;
  for (const char* f : {"image.png", "mask.png", "fit.json"})
    if (!fs::exists(dir / f))
      throw Error((dir / f).string() + ": missing (run `kinesplat perceive` and `kinesplat fit`)");
  s.photo = read_image((dir / "image.png").string(), 3);
  s.mask = read_image((dir / "mask.png").string(), 1);
  s.fit = load_fit((dir / "fit.json").string());
  if (s.mask.width != s.photo.width || s.mask.height != s.photo.height)
    throw Error((dir / "mask.png").string() + ": not the size of image.png");
  if (s.fit.camera.width != s.photo.width || s.fit.camera.height != s.photo.height)
    throw Error((dir / "fit.json").string() + ": its camera is " +
                std::to_string(s.fit.camera.width) + "x" + std::to_string(s.fit.camera.height) +
                ", image.png " + std::to_string(s.photo.width) + "x" +
                std::to_string(s.photo.height));
  return s;
}

Dataset new_dataset(const SubjectFit& fit, const GenerateOptions& o) {
  Dataset ds;
  ds.body_model = fit.body_model;
  ds.betas = fit.params.betas;
  for (int k = 0; k < 3; ++k) ds.background[k] = float(o.background(k));
  return ds;
}

// A frame's camera for an image of w x h: the pose's camera scaled (the same aspect ratio).
Camera frame_camera(const Camera& c, int w, int h, const std::string& what) {
  if (w == c.width && h == c.height) return c;
  if (std::abs(double(w) / h - double(c.width) / c.height) > 0.01 * double(c.width) / c.height)
    throw Error(what + " is " + std::to_string(w) + "x" + std::to_string(h) +
                ", not the poses' aspect ratio (" + std::to_string(c.width) + "x" +
                std::to_string(c.height) + ")");
  Camera s = c;
  const double sx = double(w) / c.width, sy = double(h) / c.height;
  s.fx *= sx, s.cx *= sx, s.fy *= sy, s.cy *= sy;
  s.width = w, s.height = h;
  return s;
}

// Frames a generator left in `dir` (NNNN.png, masks/NNNN.png optional) into the dataset; masks
// it did not give come from perceive's segmenter (on the frame composited on the background).
int ingest_frames(const fs::path& dir, const PoseSequence& poses, const fs::path& root, Dataset& ds,
                  const GenerateOptions& o) {
  const size_t n = poses.frames.size();
  for (size_t i = 0; i < n; ++i)
    if (!fs::exists(dir / frame_name(i)))
      throw Error("generate: " + (dir / frame_name(i)).string() + " missing (the generator " +
                  "must write one frame per pose: " + std::to_string(n) + ", 0000.png on)");
  int segmented = 0;
  Progress progress("generate: frames", long(n));
  for (size_t i = 0; i < n; ++i) {
    const std::string img_path = (dir / frame_name(i)).string();
    Image img = read_image(img_path, 3);
    const Camera cam = frame_camera(poses.frames[i].camera, img.width, img.height, img_path);
    Image mask;
    const fs::path mpath = dir / "masks" / frame_name(i);
    if (fs::exists(mpath)) {
      mask = read_image(mpath.string(), 1);
      if (mask.width != img.width || mask.height != img.height)
        throw Error(mpath.string() + ": not the size of its frame");
    } else {
      PerceiveOptions po;
      po.max_size = 0;
      po.face = false;
      const fs::path tmp = root.parent_path() / (".segment_" + std::to_string(::getpid()));
      try {
        run_perceive(img_path, tmp.string(), po);
        mask = read_image((tmp / "mask.png").string(), 1);
      } catch (...) {
        fs::remove_all(tmp);
        throw;
      }
      fs::remove_all(tmp);
      ++segmented;
    }
    // Composite on the dataset's background (the generator's own background may differ).
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x) {
        const float a = std::clamp(mask.at(x, y, 0), 0.f, 1.f);
        for (int c = 0; c < 3; ++c)
          img.at(x, y, c) = a * img.at(x, y, c) + (1 - a) * float(o.background(c));
      }
    DatasetFrame f;
    f.image = "images/" + frame_name(i + 1);
    f.mask = "masks/" + frame_name(i + 1);
    write_png((root / f.image).string(), img);
    write_png((root / f.mask).string(), mask);
    f.pose = poses.frames[i].pose;
    f.pose.betas.resize(0);
    f.camera = cam;
    ds.frames.push_back(std::move(f));
    if (o.progress) progress.update(long(i + 1));
  }
  if (o.progress) progress.finish();
  return segmented;
}

// Replaces {key} with the shell-quoted value (docs/generate.md); an unknown {key} is an error.
std::string substitute(const std::string& cmd, const std::map<std::string, std::string>& values) {
  std::string out;
  for (size_t i = 0; i < cmd.size();) {
    if (cmd[i] == '{') {
      const size_t e = cmd.find('}', i);
      if (e != std::string::npos) {
        const std::string key = cmd.substr(i + 1, e - i - 1);
        auto it = values.find(key);
        if (it == values.end())
          throw Error("generate: the command names {" + key +
                      "}, which is not one of {ref} "
                      "{mask} {conditions} {poses} {video} {out} {frames} {width} {height} {fps}");
        out += shell_quote(it->second);
        i = e + 1;
        continue;
      }
    }
    out += cmd[i++];
  }
  return out;
}

}  // namespace

GenerateReport generate_lift(const std::string& subject_dir, const SubjectFit& fit,
                             const PoseSequence& poses, const std::string& out_dir,
                             const GenerateOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  const fs::path sdir(subject_dir);
  const Image photo = read_image((sdir / "image.png").string(), 3);
  const std::string mask_path = (sdir / "mask.png").string();
  if (!fs::exists(mask_path)) throw Error(mask_path + ": missing (run `kinesplat perceive`)");
  const Image mask = read_image(mask_path, 1);
  GenerateReport rep;
  rep.generator = to_string(Generator::kLift);
  const SynthPerson person = lift_person(photo, mask, fit, o.lift, &rep.lift);

  StagedDir staged(out_dir);
  const fs::path root = staged.staging();
  Dataset ds = new_dataset(fit, o);
  ds.frames.push_back(photo_frame(root, photo, mask, fit, o));
  Progress progress("generate", long(poses.frames.size()));
  for (size_t i = 0; i < poses.frames.size(); ++i) {
    const PosedPerson posed = pose_synth_person(person, poses.frames[i].pose);
    const MeshRenderOutput r =
        render_synth(person, posed, poses.frames[i].camera, o.supersample, o.background);
    DatasetFrame f;
    f.image = "images/" + frame_name(i + 1);
    f.mask = "masks/" + frame_name(i + 1);
    write_png((root / f.image).string(), r.rgb);
    write_png((root / f.mask).string(), r.mask);
    f.pose = synth_params(person, poses.frames[i].pose);
    f.pose.betas.resize(0);
    f.camera = poses.frames[i].camera;
    ds.frames.push_back(std::move(f));
    if (o.progress) progress.update(long(i + 1));
  }
  ds.save(root.string());
  staged.commit();
  if (o.progress) progress.finish();
  rep.frames = int(ds.frames.size());
  rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return rep;
}

GenerateReport run_generate(const std::string& prior_dir, const std::string& subject_dir,
                            const GenerateOptions& o) {
  const fs::path prior(prior_dir);
  const std::string poses_path = (prior / "poses.json").string();
  if (!fs::exists(poses_path)) throw Error(poses_path + ": missing (run `kinesplat sample` first)");
  const PoseSequence poses = load_poses(poses_path);
  const Subject s = load_subject(subject_dir);
  if (poses.model->num_vertices() != s.fit.model->num_vertices())
    throw Error(poses_path + ": its body model differs from the subject's fit");
  const fs::path out = prior / "dataset";
  if (o.generator == Generator::kLift)
    return generate_lift(subject_dir, s.fit, poses, out.string(), o);

  const auto t0 = std::chrono::steady_clock::now();
  GenerateReport rep;
  rep.generator = to_string(o.generator);
  StagedDir staged(out.string());
  const fs::path root = staged.staging();
  fs::path frames_dir;
  if (o.generator == Generator::kCommand) {
    if (o.command.empty()) throw Error("generate: --with command needs --command");
    frames_dir = root.parent_path() / (".generator_out_" + std::to_string(::getpid()));
    fs::remove_all(frames_dir);
    fs::create_directories(frames_dir);
    const Camera& c = poses.frames.front().camera;
    char fps[32];
    std::snprintf(fps, sizeof fps, "%g", poses.fps);
    const std::map<std::string, std::string> values = {
        {"ref", fs::absolute(fs::path(subject_dir) / "image.png").string()},
        {"mask", fs::absolute(fs::path(subject_dir) / "mask.png").string()},
        {"conditions", fs::absolute(prior / "conditions").string()},
        {"poses", fs::absolute(poses_path).string()},
        {"video", fs::absolute(prior / "conditions" / "dwpose.mp4").string()},
        {"out", fs::absolute(frames_dir).string()},
        {"frames", std::to_string(poses.frames.size())},
        {"width", std::to_string(c.width)},
        {"height", std::to_string(c.height)},
        {"fps", fps}};
    const std::string cmd = substitute(o.command, values);
    const std::string log = (prior / "generate_command.log").string();
    fs::remove(log);
    if (o.progress) std::fprintf(stderr, "generate: running %s\n", cmd.c_str());
    const int status = run_shell(cmd, log);
    if (status != 0) {
      fs::remove_all(frames_dir);
      throw Error("generate: the command exited with status " + std::to_string(status) +
                  " (its output: " + log + ")\n" + log_tail(log));
    }
  } else {
    if (o.frames_dir.empty()) throw Error("generate: --with frames needs --frames DIR");
    frames_dir = o.frames_dir;
    if (!fs::is_directory(frames_dir)) throw Error(o.frames_dir + ": not a directory");
  }
  Dataset ds = new_dataset(s.fit, o);
  ds.frames.push_back(photo_frame(root, s.photo, s.mask, s.fit, o));
  try {
    rep.masks_segmented = ingest_frames(frames_dir, poses, root, ds, o);
  } catch (...) {
    if (o.generator == Generator::kCommand) fs::remove_all(frames_dir);
    throw;
  }
  if (o.generator == Generator::kCommand) fs::remove_all(frames_dir);
  ds.save(root.string());
  staged.commit();
  rep.frames = int(ds.frames.size());
  rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return rep;
}

const std::vector<std::string>& generator_names() {
  static const std::vector<std::string> n = {"lift", "command", "frames"};
  return n;
}

const char* to_string(Generator g) {
  return generator_names()[size_t(g)].c_str();
}

Generator parse_generator(const std::string& name) {
  return parse_name<Generator>(generator_names(), name, "generator");
}

}  // namespace ks
