#pragma once
// `track`'s input as a list of frames: a video (decoded by ffmpeg into PNGs), a folder of frames
// (PNG / JPEG, sorted by name) or several image files; every K-th kept, at most N evenly spread.
#include <string>
#include <vector>

namespace ks {

struct TrackInputOptions {
  int every = 1;            // keep every K-th frame of the input (1: all)
  int max_frames = 0;       // at most this many of those, evenly spread (0: all)
  double image_fps = 30.0;  // the frame rate given to a folder or a set of images
};

struct InputFrame {
  std::string path;    // the image file (for a video: the decoded PNG)
  std::string source;  // what to call it: the image's file name, or "VIDEO#n"
  int index = 0;       // the frame's number in the input (before --every / --max-frames)
  double time_s = 0;   // index / fps
};

struct TrackInput {
  bool video = false;
  bool sequence = false;  // a video or a folder: frames in time order (not a set of photos)
  double fps = 30.0;      // the input's frame rate (the video's, or image_fps)
  int total = 0;          // frames in the input
  std::vector<InputFrame> frames;  // the kept ones, in order
};

// Which frames of `count` (already every K-th) are kept: all, or max_frames evenly spread
// (the first and the last always).
std::vector<int> spread_frames(int count, int max_frames);

// The frames of `inputs`: one video file, one folder, or image files (.png, .jpg, .jpeg).
// A video is decoded into `decode_dir` (created; the caller removes it). Throws ks::Error naming
// the input: missing, not a video or image ffmpeg can read, an empty folder, frames of different
// sizes (naming two of them), a video mixed with other inputs.
TrackInput list_track_input(const std::vector<std::string>& inputs, const std::string& decode_dir,
                            const TrackInputOptions& options = {});

// The frame rate of a video as ffprobe (beside ffmpeg) reports it; 0 when unknown.
double video_fps(const std::string& path);

}  // namespace ks
