// `kinesplat track`: the body in every frame of a video, a folder of frames or a set of photos,
// with one camera focal and one body shape (docs/track.md).
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "cli/registry.hpp"
#include "core/error.hpp"
#include "track/track.hpp"

namespace {

ks::cli::CommandGroup group(25, [](CLI::App& app) {
  struct Args {
    ks::TrackOptions o;
    std::vector<std::string> inputs;
    std::string out;
    std::string keypoints = ks::to_string(o.fit.keypoints);
    bool quiet = false, no_overlay = false, no_temporal = false, shared_pass = false;
  };
  auto a = std::make_shared<Args>();
  auto* sub = app.add_subcommand(
      "track",
      "Fit the body in every frame of a video, a folder of frames or several photos: one camera "
      "focal and one body shape for all, a video's frames tied in time (TRACK/track.json, "
      "TRACK/motion.npz, TRACK/frames/)");
  sub->add_option("input", a->inputs,
                  "A video file (anything ffmpeg reads), a folder of PNG / JPEG frames (sorted by "
                  "name) or several image files")
      ->required();
  sub->add_option("--out", a->out, "Output folder TRACK (replaced if it is an earlier output)")
      ->required();
  sub->add_option("--every", a->o.input.every, "Keep every K-th frame")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  sub->add_option("--max-frames", a->o.input.max_frames,
                  "At most this many frames, evenly spread (0: all)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  auto* focal = sub->add_option(
      "--focal", a->o.fit.focal,
      "Focal length in pixels of the frames as perceive writes them "
      "(image.png; default: the photos' EXIF focal where they all give the same one, "
      "else from --fov)");
  auto* fov = sub->add_option("--fov", a->o.fit.fov_degrees,
                              "Field of view across the frame's long side, degrees, when --focal "
                              "is not given")
                  ->capture_default_str()
                  ->check(CLI::Range(1.0, 170.0));
  focal->excludes(fov);
  sub->add_option("--body", a->o.body, "Body model: 'default' or an SMPL / SMPL-X .npz")
      ->capture_default_str();
  sub->add_option("--keypoints", a->keypoints,
                  "What the keypoints mark: 'coco' (the detector's) or 'joints'")
      ->capture_default_str()
      ->check(CLI::IsMember(ks::keypoint_convention_names()));
  sub->add_option("--max-size", a->o.perceive.max_size,
                  "Longer side of each frame's image.png (0: the input's size)")
      ->capture_default_str();
  sub->add_flag("--no-overlay", a->no_overlay,
                "Without TRACK/overlay.mp4 and the frames' fit_overlay.png");
  sub->add_flag("--no-temporal", a->no_temporal,
                "Without pass 3 (a video's or folder's frames fitted at once with the temporal "
                "terms); photo sets never have it");
  sub->add_option("--sigma-accel", a->o.temporal.sigma_accel,
                  "Pass 3's acceleration prior: deviation density of the joints' acceleration, "
                  "m s^-1.5 (larger: less smoothing)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  sub->add_flag("--shared-pass", a->shared_pass,
                "Where pass 3 runs, pass 2 before it as well (each frame refitted with the shared "
                "shape; without it pass 3 starts from pass 1: the same accuracy on the synth in "
                "half the time)");
  sub->add_flag("--temporal-silhouette", a->o.temporal.silhouette,
                "Pass 3 with the silhouette terms too: outlines closer to the masks, joints "
                "further from the truth on the synth (docs/track.md), about 10x slower");
  sub->add_option("--avatar", a->o.avatar,
                  "Pass 4: register every frame's pose and global transform through this "
                  "avatar's render (docs/register.md); track.json keeps the keypoint track's "
                  "params beside")
      ->check(CLI::ExistingFile);
  sub->add_flag("--quiet,-q", a->quiet, "No progress lines");
  sub->callback([a] {
    ks::TrackOptions o = a->o;
    o.progress = !a->quiet;
    if (a->no_overlay) o.overlay = false;
    if (a->no_temporal) o.temporal.enabled = false;
    if (a->shared_pass) o.shared_pass = true;
    o.fit.keypoints = ks::parse_keypoint_convention(a->keypoints);
    const ks::TrackResult r = ks::run_track(a->inputs, a->out, o);
    std::printf("track: %zu frames, focal %.1f px, %zu skipped; wrote %s/track.json, motion.npz\n",
                r.frames.size(), r.focal, r.skipped.size(), a->out.c_str());
    for (const auto& s : r.skipped) std::printf("  skipped %s\n", s.c_str());
  });
});

}  // namespace
