#pragma once
// `create`: one photo -> an animatable avatar, every stage of the pipeline in order, each the same
// library call its own command runs (so a user can stop, edit a stage's output and go on):
//   perceive  PHOTO            -> DIR/subject/{image,mask}.png, keypoints.json, perceive.json
//   fit       DIR/subject      -> DIR/subject/fit.json (and fit_overlay.png)
//   sample    DIR/subject      -> DIR/prior/poses.json, DIR/prior/conditions/
//   generate  DIR/prior        -> DIR/prior/dataset/ (the photo is frame 0, weighted more)
//   augment   DIR/prior        -> DIR/prior/refined/
//   reconstruct DIR/prior/refined -> DIR/avatar.ksavatar
//   videos    DIR/avatar.ksavatar -> DIR/turntable.mp4, DIR/MOTION.mp4
// Resumable: a stage is skipped when all its outputs exist, are newer than all its inputs and were
// made with the same settings (recorded in DIR/create.json); `force` reruns everything.
// DIR/create.json records each stage's time, whether it was skipped, the settings, the status
// ("running", "done", "failed" with the error) and the peak memory.
#include <string>
#include <vector>

#include "animate/playback.hpp"
#include "augment/augment.hpp"
#include "fit/run_fit.hpp"
#include "generate/generate.hpp"
#include "perceive/perceive.hpp"
#include "reconstruct/reconstruct.hpp"
#include "sample/sample.hpp"

namespace ks {

struct CreateOptions {
  CreateOptions();
  PerceiveOptions perceive;
  FitStageOptions fit;
  SampleOptions sample;
  GenerateOptions generate;
  AugmentOptions augment;
  ReconstructOptions reconstruct;
  // The generated frames' longer side at most this many pixels (the fit camera scaled down; the
  // photo, frame 0, keeps its size). 0: the photo's size.
  int max_frame_side = 768;
  // Videos of the avatar: a turntable (the `turn` motion, fixed front camera), then these motions.
  std::vector<std::string> motions = {"dance"};
  PlaybackOptions playback;
  bool force = false;
  bool progress = true;
};

struct CreateStage {
  std::string name;
  double seconds = 0;
  bool skipped = false;
};

struct CreateReport {
  std::string out_dir, subject_dir, prior_dir, avatar;
  std::vector<std::string> videos;
  std::vector<CreateStage> stages;
  double seconds = 0;
  double peak_rss_mb = 0;  // this process
};

// The stages' names, in order.
const std::vector<std::string>& create_stage_names();

// Checks the options and the photo before anything runs (ks::Error naming what is wrong). On a
// failure DIR/create.json says "failed" with the error, the failing stage's outputs are not left
// half-written (each stage writes atomically) and the error is rethrown.
CreateReport run_create(const std::string& photo, const std::string& out_dir,
                        const CreateOptions& options = {});

}  // namespace ks
