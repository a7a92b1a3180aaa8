#include "track/track_input.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "core/error.hpp"
#include "core/fileio.hpp"
#include "core/process.hpp"
#include "io/image_decode.hpp"
#include "io/video.hpp"

namespace fs = std::filesystem;

namespace ks {

namespace {

bool is_image_name(const fs::path& p) {
  std::string e = p.extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return std::tolower(c); });
  return e == ".png" || e == ".jpg" || e == ".jpeg";
}

// The image's size from its header; throws naming the file when it is not an image.
std::pair<int64_t, int64_t> image_size(const std::string& path) {
  int64_t w = 0, h = 0;
  if (!image_header_size(read_file_bytes(path), w, h))
    throw Error("track: " + path + " is not a PNG or JPEG image");
  return {w, h};
}

std::string ffprobe_beside(const std::string& ffmpeg) {
  const fs::path p = fs::path(ffmpeg).parent_path() / "ffprobe";
  std::error_code ec;
  return fs::is_regular_file(p, ec) ? p.string() : "";
}

// Decodes every `every`-th frame of `video` into dir/NNNNNN.png; returns how many were written.
int decode_video(const std::string& video, const std::string& dir, int every) {
  const std::string ffmpeg = find_ffmpeg();
  if (ffmpeg.empty())
    throw Error("track: reading the video " + video +
                " needs ffmpeg, which was not found on PATH (install it, e.g. `apt-get install "
                "ffmpeg`)");
  fs::create_directories(dir);
  const std::string log = (fs::path(dir) / "ffmpeg.log").string();
  std::string filter;
  if (every > 1)
    filter = " -vf " + shell_quote("select=not(mod(n\\," + std::to_string(every) + "))");
  const std::string cmd = shell_quote(ffmpeg) + " -nostdin -v error -i " + shell_quote(video) +
                          " -map 0:v:0" + filter + " -vsync 0 -start_number 0 " +
                          shell_quote((fs::path(dir) / "%06d.png").string());
  const int rc = run_shell(cmd, log);
  int n = 0;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".png") ++n;
  if (rc != 0 || n == 0)
    throw Error("track: " + video + " is not a video or image that ffmpeg can read" +
                (rc != 0 ? " (ffmpeg: " + log_tail(log, 300) + ")" : " (no frames)"));
  return n;
}

}  // namespace

std::vector<int> spread_frames(int count, int max_frames) {
  std::vector<int> out;
  if (count <= 0) return out;
  if (max_frames <= 0 || max_frames >= count) {
    for (int i = 0; i < count; ++i) out.push_back(i);
    return out;
  }
  if (max_frames == 1) return {0};
  for (int i = 0; i < max_frames; ++i)
    out.push_back(int(std::lround(double(i) * (count - 1) / (max_frames - 1))));
  return out;
}

double video_fps(const std::string& path) {
  const std::string ffprobe = ffprobe_beside(find_ffmpeg());
  if (ffprobe.empty()) return 0;
  const std::string cmd = shell_quote(ffprobe) +
                          " -v error -select_streams v:0 -show_entries stream=avg_frame_rate -of "
                          "default=nw=1:nk=1 " +
                          shell_quote(path);
  FILE* p = ::popen(cmd.c_str(), "r");
  if (!p) return 0;
  char buf[128] = {0};
  const bool got = std::fgets(buf, sizeof buf, p) != nullptr;
  ::pclose(p);
  if (!got) return 0;
  double num = 0, den = 1;
  if (std::sscanf(buf, "%lf/%lf", &num, &den) < 1) return 0;
  if (!(den > 0)) return 0;
  const double fps = num / den;
  return std::isfinite(fps) && fps > 0 ? fps : 0;
}

TrackInput list_track_input(const std::vector<std::string>& inputs, const std::string& decode_dir,
                            const TrackInputOptions& o) {
  if (inputs.empty()) throw Error("track: no input given");
  if (o.every < 1) throw Error("track: --every must be at least 1");
  for (const auto& in : inputs)
    if (!fs::exists(in)) throw Error("track: " + in + " does not exist");
  TrackInput t;
  std::vector<std::string> files;  // every frame of the input, in order
  const bool one = inputs.size() == 1;
  if (one && fs::is_directory(inputs[0])) {
    for (const auto& e : fs::directory_iterator(inputs[0]))
      if (e.is_regular_file() && is_image_name(e.path())) files.push_back(e.path().string());
    std::sort(files.begin(), files.end());
    if (files.empty()) throw Error("track: the folder " + inputs[0] + " has no PNG or JPEG frames");
    t.fps = o.image_fps;
    t.sequence = true;
  } else if (one && !is_image_name(inputs[0])) {
    t.video = true;
    t.sequence = true;
    decode_video(inputs[0], decode_dir, o.every);  // ffmpeg keeps every K-th frame itself
    for (const auto& e : fs::directory_iterator(decode_dir))
      if (e.path().extension() == ".png") files.push_back(e.path().string());
    std::sort(files.begin(), files.end());
    const double fps = video_fps(inputs[0]);
    t.fps = fps > 0 ? fps : 30.0;
  } else {
    for (const auto& in : inputs) {
      if (fs::is_directory(in))
        throw Error("track: give one folder alone, not " + in + " among others");
      if (!is_image_name(in))
        throw Error("track: " + in +
                    " is not a PNG or JPEG image (a video must be the only input)");
      files.push_back(in);
    }
    t.fps = o.image_fps;
  }
  // Each file's frame number in the input, and every K-th of them.
  const int step = t.video ? 1 : o.every;
  const int number_scale = t.video ? o.every : 1;
  t.total = int(files.size()) * number_scale;
  std::vector<int> every;
  for (int i = 0; i < int(files.size()); i += step) every.push_back(i);
  const std::vector<int> kept = spread_frames(int(every.size()), o.max_frames);
  std::pair<int64_t, int64_t> size0{-1, -1};
  std::string first;
  for (int k : kept) {
    InputFrame f;
    f.path = files[size_t(every[size_t(k)])];
    f.index = every[size_t(k)] * number_scale;
    f.source = t.video ? fs::path(inputs[0]).filename().string() + "#" + std::to_string(f.index)
                       : fs::path(f.path).filename().string();
    f.time_s = f.index / t.fps;
    const auto size = image_size(f.path);
    if (size0.first < 0) {
      size0 = size;
      first = f.path;
    } else if (size != size0) {
      throw Error("track: the frames differ in size: " + first + " is " +
                  std::to_string(size0.first) + "x" + std::to_string(size0.second) + ", " + f.path +
                  " is " + std::to_string(size.first) + "x" + std::to_string(size.second));
    }
    t.frames.push_back(std::move(f));
  }
  return t;
}

}  // namespace ks
