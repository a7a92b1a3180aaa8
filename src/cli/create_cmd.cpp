// `kinesplat create PHOTO --out DIR`: photo -> avatar, every stage in order (create/create.hpp).
#include <cstdio>
#include <memory>
#include <string>

#include "cli/parse.hpp"
#include "cli/registry.hpp"
#include "core/error.hpp"
#include "create/create.hpp"

namespace {

// The defaults are the library's (CreateOptions); the flags only override them.
struct Args {
  ks::CreateOptions o;
  std::string photo, out, motions, size;
  std::string generator = ks::to_string(o.generate.generator);
  std::string keypoints = ks::to_string(o.fit.fit.keypoints);
  bool no_face_fusion = false, quiet = false;
};

ks::cli::CommandGroup group(29, [](CLI::App& app) {
  auto a = std::make_shared<Args>();
  auto* sub = app.add_subcommand(
      "create",
      "One photo -> an animatable avatar: perceive, fit, sample, generate, augment, reconstruct, "
      "videos into DIR (resumable: stages whose outputs are newer than their inputs are skipped)");
  sub->add_option("photo", a->photo, "The photo (PNG or JPEG) of one person, whole body")
      ->required();
  sub->add_option("--out,-o", a->out,
                  "Output folder DIR: subject/, prior/, avatar.ksavatar, turntable.mp4, "
                  "MOTION.mp4, create.json")
      ->required();
  sub->add_option("--generator", a->generator,
                  "Frames in pose space from: lift (built in, no weights), command (your "
                  "video-diffusion model, --command), frames (frames you have, "
                  "--generated-frames)")
      ->capture_default_str()
      ->check(CLI::IsMember(ks::generator_names()));
  sub->add_option("--command", a->o.generate.command,
                  "With --generator command: its command line (placeholders in docs/generate.md)");
  sub->add_option("--generated-frames", a->o.generate.frames_dir,
                  "With --generator frames: a folder of NNNN.png, one per sampled pose");
  sub->add_option("--frames", a->o.sample.frames, "Number of sampled poses")
      ->capture_default_str()
      ->check(CLI::Range(1, 4096));
  sub->add_option("--iters", a->o.reconstruct.train.iterations, "Reconstruct steps")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000000));
  sub->add_option("--subdivide", a->o.reconstruct.train.subdivide,
                  "Reconstruct: Loop subdivision levels of the body template (each level about 4x "
                  "the Gaussians; 0 for a small, quick avatar)")
      ->capture_default_str()
      ->check(CLI::Range(0, 3));
  sub->add_option("--density", a->o.reconstruct.density, "Density control: gpdc|vertex|naive|off")
      ->capture_default_str();
  sub->add_option("--seed", a->o.reconstruct.train.seed, "Reconstruct's random seed")
      ->capture_default_str();
  sub->add_option("--body", a->o.fit.body, "Body model: 'default' or an SMPL / SMPL-X .npz")
      ->capture_default_str();
  sub->add_option("--keypoints-file", a->o.perceive.keypoints_path,
                  "Your keypoints for the photo (OpenPose/DWPose or COCO JSON) instead of the "
                  "detector's");
  sub->add_option("--mask", a->o.perceive.mask_path, "Your person mask instead of the detector's");
  sub->add_option("--keypoints", a->keypoints,
                  "What the keypoints mark: coco (detectors, annotators) or joints (the body "
                  "model's joints, e.g. synth's photo_keypoints.json)")
      ->capture_default_str()
      ->check(CLI::IsMember(ks::keypoint_convention_names()));
  sub->add_option("--keypoints-pixel-centre", a->o.perceive.keypoints_pixel_centre,
                  "Where --keypoints-file puts the centre of the top-left pixel: 0 (OpenPose, "
                  "COCO) or 0.5 (kinesplat's files)")
      ->check(CLI::IsMember({0.0, 0.5}));
  sub->add_option("--focal", a->o.fit.fit.focal,
                  "Focal length of the photo in pixels of subject/image.png (default: the photo's "
                  "EXIF focal, else a 40 degree field of view)");
  sub->add_flag("--no-face-fusion", a->no_face_fusion, "augment: do not fuse the photo's face");
  sub->add_option("--face-warp", a->o.augment.face_warp,
                  "augment: body (through the fitted body, turning with the head) or similarity")
      ->capture_default_str()
      ->check(CLI::IsMember({"body", "similarity"}));
  sub->add_option("--restore", a->o.augment.restore_command,
                  "augment: a restoration command run on each frame ({in} {out})");
  std::string default_motions;
  for (const auto& m : a->o.motions) default_motions += (default_motions.empty() ? "" : ",") + m;
  sub->add_option("--motions", a->motions,
                  "Motion videos besides the turntable, comma-separated (built-in names or AMASS "
                  ".npz; default " +
                      (default_motions.empty() ? std::string("none") : default_motions) +
                      "; 'none' for none)");
  sub->add_option("--size", a->size,
                  "Video size WxH (default " + std::to_string(a->o.playback.width) + "x" +
                      std::to_string(a->o.playback.height) + ")");
  sub->add_flag("--force", a->o.force, "Rerun every stage");
  sub->add_flag("--quiet,-q", a->quiet,
                "No progress bars: only each stage's lines and the summary");
  sub->callback([a] {
    ks::CreateOptions o = a->o;
    o.generate.generator = ks::parse_generator(a->generator);
    if (o.generate.generator != ks::Generator::kCommand && !o.generate.command.empty())
      throw ks::Error("--command is for --generator command");
    if (o.generate.generator != ks::Generator::kFrames && !o.generate.frames_dir.empty())
      throw ks::Error("--generated-frames is for --generator frames");
    o.fit.fit.keypoints = ks::parse_keypoint_convention(a->keypoints);
    o.augment.face_fusion = !a->no_face_fusion;
    if (!a->motions.empty()) {
      o.motions.clear();
      if (a->motions != "none") {
        size_t b = 0;
        while (b <= a->motions.size()) {
          size_t e = a->motions.find(',', b);
          if (e == std::string::npos) e = a->motions.size();
          const std::string m = a->motions.substr(b, e - b);
          if (m.empty()) throw ks::Error("--motions: an empty name in \"" + a->motions + "\"");
          o.motions.push_back(m);
          b = e + 1;
        }
      }
    }
    if (!a->size.empty())
      ks::cli::parse_image_size(a->size, "--size", o.playback.width, o.playback.height);
    o.progress = !a->quiet;
    const ks::CreateReport r = ks::run_create(a->photo, a->out, o);
    std::printf("\ncreate: done in %.0f s (peak memory %.0f MB)\n", r.seconds, r.peak_rss_mb);
    for (const auto& s : r.stages)
      std::printf("  %-12s %s\n", s.name.c_str(),
                  s.skipped ? "up to date" : (std::to_string(int(s.seconds + 0.5)) + " s").c_str());
    std::printf("subject (photo, mask, keypoints, fit): %s\n", r.subject_dir.c_str());
    std::printf("prior (poses, conditions, frames):     %s\n", r.prior_dir.c_str());
    std::printf("avatar:                                %s\n", r.avatar.c_str());
    for (const auto& v : r.videos)
      std::printf("video:                                 %s\n", v.c_str());
  });
});

}  // namespace
