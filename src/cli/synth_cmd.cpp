// `kinesplat synth`: a synthetic clothed person with exact ground truth (photo, keypoints,
// subject parameters, a training sequence along a motion and novel-pose test views).
#include <cstdio>
#include <string>

#include "cli/parse.hpp"
#include "cli/registry.hpp"
#include "core/error.hpp"
#include "synth/run.hpp"

namespace {

struct Opts {
  ks::SynthRunConfig cfg;
  std::string size;  // empty: the config's size
  long long seed = 0;
};

ks::cli::CommandGroup group(20, [](CLI::App& app) {
  auto o = std::make_shared<Opts>();
  auto* sub = app.add_subcommand(
      "synth", "Generate a synthetic clothed person with exact ground truth (photo, train, test)");
  sub->add_option("--seed", o->seed, "Random seed (body shape, colours, garments)")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--out", o->cfg.out_dir, "Output directory")->required();
  sub->add_option("--size", o->size,
                  "Image size WIDTHxHEIGHT (default " + std::to_string(o->cfg.width) + "x" +
                      std::to_string(o->cfg.height) + ")");
  sub->add_option("--frames", o->cfg.frames,
                  "Frames of the training sequence (the motion sampled at this many)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  sub->add_option("--motion", o->cfg.motion,
                  "The training sequence's motion: a built-in name (`kinesplat motions`) or an "
                  "AMASS .npz")
      ->capture_default_str();
  sub->add_option("--camera", o->cfg.camera,
                  "The training sequence's camera: fixed (one front camera) or orbit (once round "
                  "the body over the sequence)")
      ->capture_default_str()
      ->check(CLI::IsMember({"fixed", "orbit"}));
  sub->add_flag("--video", o->cfg.video,
                "Also write train/video.mp4 (the training frames at the motion's frame rate)");
  sub->add_option("--body", o->cfg.body_model, "Body model: 'default' or a model .npz");
  sub->add_option("--supersample", o->cfg.supersample, "Anti-aliasing: SxS samples per pixel")
      ->check(CLI::Range(1, 8));
  sub->add_option("--photo-pose", o->cfg.photo_pose,
                  "The photo's pose: MOTION:FRAME of a built-in motion (default: standing)");
  sub->add_option("--photo-azimuth", o->cfg.photo_azimuth,
                  "Azimuth of the photo's camera about the body, degrees (0: front, 90: its left)");
  sub->add_option("--levels", o->cfg.options.subdivision_levels,
                  "Loop subdivision levels of the body mesh (default 2)")
      ->check(CLI::Range(0, 3));
  sub->callback([o] {
    if (!o->size.empty()) ks::cli::parse_image_size(o->size, "--size", o->cfg.width, o->cfg.height);
    o->cfg.seed = uint64_t(o->seed);
    ks::run_synth(o->cfg);
    std::fprintf(stderr, "synth: wrote %s\n", o->cfg.out_dir.c_str());
  });
});

}  // namespace
