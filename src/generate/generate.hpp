#pragma once
// `generate`: the generator G(I_ref; p_1..p_N) -> frames, written as the project's dataset
// (PRIOR/dataset/: dataset.json, images/, masks/). Frame 0 is the photo itself at the fitted pose
// and camera (composited on the dataset's background with its mask, weighted more: it is the one
// frame that is certainly right); frames 1..N are the generator's, one per pose of
// PRIOR/poses.json (`sample`). Backends:
//  - lift: built in, no weights (generate/lift.hpp): the lifted person rendered in every pose;
//  - command: an external program under the contract of docs/generate.md (a video-diffusion
//    model: MusePose, Champ, ...), given the reference image and the condition renders on disk,
//    returning one frame per pose (masks optional: else perceive's segmenter makes them);
//  - frames: frames the user already has, one per pose, in a folder (same layout).
#include <Eigen/Core>
#include <string>
#include <vector>

#include "fit/fit_file.hpp"
#include "generate/lift.hpp"
#include "sample/poses_file.hpp"

namespace ks {

enum class Generator { kLift, kCommand, kFrames };

// "lift" / "command" / "frames", and back (ks::Error naming the value for any other name).
const char* to_string(Generator g);
Generator parse_generator(const std::string& name);
// Every generator's name, in the enum's order.
const std::vector<std::string>& generator_names();

struct GenerateOptions {
  Generator generator = Generator::kLift;
  LiftOptions lift;
  int supersample = 3;        // anti-aliasing of the lift renders (S x S samples per pixel)
  double photo_weight = 8.0;  // frame 0 (the photo) counts this many frames in a fit
  Eigen::Vector3d background = Eigen::Vector3d::Ones();
  // command: the command line, run by /bin/sh, with {ref} {mask} {conditions} {poses} {video}
  // {out} {frames} {width} {height} {fps} replaced by shell-quoted values (docs/generate.md).
  std::string command;
  std::string frames_dir;  // frames: the folder with NNNN.png (and masks/NNNN.png)
  bool progress = true;
};

struct GenerateReport {
  int frames = 0;  // including the photo
  double seconds = 0;
  std::string generator;
  int masks_segmented = 0;  // generator frames whose masks perceive's segmenter made
  LiftReport lift;
};

// The subject's photo (SUBJECT/image.png, mask.png) and fit, the poses of PRIOR/poses.json:
// writes PRIOR/dataset/ as a whole (atomically: a failed run leaves none).
GenerateReport run_generate(const std::string& prior_dir, const std::string& subject_dir,
                            const GenerateOptions& options = {});

// The lift backend alone, from a fit and poses in memory, into `out_dir` (the dataset folder).
GenerateReport generate_lift(const std::string& subject_dir, const SubjectFit& fit,
                             const PoseSequence& poses, const std::string& out_dir,
                             const GenerateOptions& options = {});

}  // namespace ks
