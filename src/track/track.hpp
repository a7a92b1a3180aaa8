#pragma once
// `kinesplat track`: the body in every frame of a video or photo set, one camera focal and one
// body shape for all frames (docs/track.md).
//   1. the input's frames (track_input.hpp): a video decoded by ffmpeg, a folder, image files;
//   2. perceive per frame with one detector helper kept warm: TRACK/frames/NNNN/ (image.png,
//      mask.png, keypoints.json, perceive.json); a frame without a person is skipped;
//   3. fit pass 1: each frame on its own (the single-photo fit's schedule); the shared shape = the
//      per-coefficient median of the frames' betas; pass 2: each frame again with that shape
//      fixed (FitOptions::initial_betas, free_betas off in every stage); pass 3 on a sequence:
//      all frames at once with the temporal terms (track/temporal.hpp);
//   (pass 4 with an avatar: each frame registered through its render, register/register.hpp);
//   4. TRACK/track.json and TRACK/motion.npz (track_file.hpp); TRACK/overlay.mp4.
// The output folder appears atomically: on any error nothing is left.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "body/body_model.hpp"
#include "fit/fit.hpp"
#include "perceive/perceive.hpp"
#include "register/register.hpp"
#include "track/temporal.hpp"
#include "track/track_input.hpp"

namespace ks {

struct TrackOptions {
  TrackInputOptions input;
  PerceiveOptions perceive;
  std::string body = "default";  // 'default' or an SMPL-family .npz
  FitOptions fit;                // focal / fov, keypoint convention; pass 1's schedule
  // Pass 3 on sequences (a video, a folder of frames; not a set of photos): all frames at once
  // with the temporal terms (track/temporal.hpp).
  TemporalOptions temporal;
  // Pass 2 before pass 3 too (where pass 3 does not run, pass 2 always does). Off: pass 3 starts
  // from pass 1's poses with the shared shape — on synth seeds 3 / 7 / 5 the same figures within
  // 0.4 mm and half the fitting time (docs/track.md).
  bool shared_pass = false;
  // Pass 4 where given: each frame's pose and global transform registered through this avatar's
  // render (register/register.hpp; the avatar's skeleton, the frame's camera), after the passes
  // above; track.json keeps the keypoint track's params beside each frame's registered ones.
  std::string avatar;
  RegisterOptions registration;
  bool progress = true;  // a line per stage and frame on stderr
  // run_track: each frame's fit drawn on it (fit/overlay.hpp) as TRACK/frames/NNNN/fit_overlay.png
  // and TRACK/overlay.mp4 (the video only where ffmpeg is found).
  bool overlay = true;
};

// One frame to fit: a subject folder as `perceive` writes it, and where it came from.
struct TrackFrameInput {
  std::string subject_dir;
  std::string source;  // the file name (or VIDEO#n)
  int index = 0;       // the frame's number in the input
  double time_s = 0;
};

struct TrackFrame {
  int index = 0;
  double time_s = 0;
  std::string source;
  std::string subject;     // the subject folder, relative to TRACK
  FitResult independent;   // pass 1: the frame on its own
  FitResult shared;        // pass 2: with the shared shape
  FitResult fit;           // the result: pass 3 (temporal) on a sequence, else pass 2
  bool swapped = false;    // pass 3 exchanged the detector's left and right labels here
  bool restarted = false;  // pass 3 restarted this frame from its neighbours
  std::vector<std::string> keypoints_used;  // BODY_25 names of the keypoints present
  bool registered = false;                  // pass 4 ran (TrackOptions::avatar)
  RegisterResult registration;              // what it did; fit.params is its result
  BodyParams keypoint_params;               // the pose before pass 4
};

struct TrackResult {
  std::string body_model = "default";
  Eigen::VectorXd betas;                     // the shared shape
  double focal = 0;                          // pixels of image.png
  std::string focal_from = "field of view";  // "option", "metadata" (EXIF), "field of view"
  int width = 0, height = 0;
  double fps = 30;  // the kept frames' rate (the input's divided by the mean step between them)
  double input_fps = 30;
  bool video = false;
  bool sequence = false;    // frames in time order (a video or a folder): pass 3 ran on them
  bool shared_pass = true;  // pass 2 ran (TrackFrame::shared is its fit)
  TemporalReport temporal;
  std::vector<TrackFrame> frames;
  std::vector<std::string> skipped;  // "SOURCE (frame n): why"
  double perceive_seconds = 0, fit_seconds = 0;
};

// Step 3 on subject folders; `frames` in time order, all of one image size; `sequence`: they are
// a video's or a folder's frames (pass 3 runs), else a set of photos. Frames whose fit fails (no
// torso) are skipped and listed. Throws ks::Error when none is left.
TrackResult fit_track(const BodyModel& model, const std::vector<TrackFrameInput>& frames,
                      const TrackOptions& options = {}, bool sequence = true);

// Steps 3-4 on subject folders the caller made (the tests give the synth's true keypoints and
// masks): TRACK/track.json and TRACK/motion.npz, written atomically.
TrackResult track_subjects(const std::vector<TrackFrameInput>& frames, const std::string& out_dir,
                           const TrackOptions& options = {}, bool sequence = true);

// The whole command: steps 1-4 into out_dir (atomically; a non-empty folder that is not an
// earlier track output is refused). Throws ks::Error on bad input, and when no frame has a person
// (naming the frames).
TrackResult run_track(const std::vector<std::string>& inputs, const std::string& out_dir,
                      const TrackOptions& options = {});

}  // namespace ks
