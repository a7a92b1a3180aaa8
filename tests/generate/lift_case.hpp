#pragma once
// A small synth person's photo, mask and true fit (the synth's subject.json), and the lift's
// starting point on it (generate/lift_body.hpp): the input of the lift's step tests.
#include <string>

#include "fit/fit_file.hpp"
#include "generate/lift.hpp"
#include "generate/lift_body.hpp"
#include "io/image_io.hpp"
#include "synth/run.hpp"
#include "temp_dir.hpp"

namespace ks::test {

struct LiftCase {
  TempDir tmp{"lift"};
  SubjectFit fit;
  Image photo, mask;
  LiftOptions options;
  lift::LiftBody body;
  // seed 0: a dress; 1: trousers (synth/appearance.hpp).
  explicit LiftCase(uint64_t seed, int subdivision_levels = 1) {
    SynthRunConfig cfg;
    cfg.seed = seed;
    cfg.out_dir = tmp / "synth";
    cfg.width = 128;
    cfg.height = 192;
    cfg.frames = 1;
    cfg.supersample = 1;
    cfg.progress = false;
    run_synth(cfg);
    fit = load_fit(cfg.out_dir + "/subject.json");
    photo = read_image(cfg.out_dir + "/photo.png", 3);
    mask = read_image(cfg.out_dir + "/photo_mask.png", 1);
    options.subdivision_levels = subdivision_levels;
    body = lift::lift_body(fit, options);
  }
};

}  // namespace ks::test
