// `kinesplat animate`: pose an avatar along a motion and render frames (PNG), an MP4 and
// optionally per-frame 3DGS .ply files (animate/playback.hpp).
#include <algorithm>
#include <cstdio>
#include <filesystem>

#include "animate/playback.hpp"
#include "avatar/avatar.hpp"
#include "cli/parse.hpp"
#include "cli/registry.hpp"
#include "core/error.hpp"
#include "raster_cuda/rasterizer_cuda.hpp"

namespace fs = std::filesystem;

namespace {

// The defaults are the library's (PlaybackOptions).
struct AnimateArgs {
  ks::PlaybackOptions d;
  std::string avatar, motion = d.motion, out, camera = d.camera,
                      size = std::to_string(d.width) + "x" + std::to_string(d.height),
                      background = "1,1,1";
  int frames = d.frames;
  bool ply = d.ply;
  float backface_cull = d.backface_cull;  // 1 = off; 0.4 is a good trade on close-fitting clothes
  std::string device = d.cuda ? "cuda" : "cpu";
};

using namespace ks;
using namespace ks::cli;

void run_animate(const AnimateArgs& args) {
  PlaybackOptions o;
  parse_image_size(args.size, "--size", o.width, o.height);
  parse_rgb(args.background, "--background", o.background);
  o.motion = args.motion;
  o.camera = args.camera;
  o.frames = args.frames;
  o.ply = args.ply;
  o.backface_cull = args.backface_cull;
  o.cuda = args.device == "cuda";
  if (o.cuda && cuda::raster_cuda_devices() == 0)
    throw Error("--device cuda: " + cuda::raster_cuda_describe());
  if (o.frames < 0) throw Error("--frames must be >= 0");
  const Avatar avatar = load_avatar(args.avatar);
  const PlaybackReport r = render_playback(avatar, args.out, o);
  if (fs::path(args.out).extension() == ".mp4") {
    if (args.ply)
      std::printf("animate: wrote %s and per-frame PNG/.ply files in %s/\n", args.out.c_str(),
                  r.frames_dir.c_str());
    else
      std::printf("animate: wrote %s\n", args.out.c_str());
  } else {
    std::printf("animate: wrote %d frames%s to %s/\n", r.frames,
                args.ply ? " (PNG + .ply)" : " (PNG)", args.out.c_str());
  }
  char cull_note[32] = "off";
  if (r.culled) std::snprintf(cull_note, sizeof cull_note, "at cos > %.2f", args.backface_cull);
  std::printf(
      "animate: pose + render %.1f ms per frame (%.1f fps; median %.1f ms, slowest %.1f ms), "
      "back-face culling %s%s\n",
      r.render_ms, 1e3 / std::max(r.render_ms, 1e-9), r.render_median_ms, r.render_max_ms,
      cull_note, o.cuda ? ", posed and rasterized on the GPU" : "");
}

ks::cli::CommandGroup group(70, [](CLI::App& app) {
  auto args = std::make_shared<AnimateArgs>();
  auto* sub = app.add_subcommand("animate", "Pose an avatar along a motion and render it");
  sub->add_option("avatar", args->avatar, "Avatar file (from `reconstruct`)")->required();
  sub->add_option("--motion", args->motion,
                  "Built-in motion name (see `kinesplat motions`) or an AMASS .npz file")
      ->capture_default_str();
  sub->add_option("--out", args->out, "Output directory for PNG frames, or FILE.mp4")->required();
  sub->add_option("--camera", args->camera, "front | orbit | camera JSON file")
      ->capture_default_str();
  sub->add_option("--size", args->size, "Image size WxH")->capture_default_str();
  sub->add_option("--frames", args->frames, "Number of frames (0: the motion's length)");
  sub->add_flag("--ply", args->ply,
                "Also write each frame as a standard 3DGS .ply (all Gaussians: turns the "
                "back-face culling off)");
  sub->add_option("--backface-cull", args->backface_cull,
                  "Skip Gaussians whose posed surface normal faces away from the camera by more "
                  "than this cosine (0-1, e.g. 0.4: ~30% faster, may leave specks in loose "
                  "clothing; 1 = off, render every Gaussian)")
      ->capture_default_str();
  sub->add_option("--background", args->background, "Background colour r,g,b in [0,1]")
      ->capture_default_str();
  sub->add_option("--device", args->device,
                  "cpu, or cuda: pose and rasterize on an NVIDIA GPU (a build with -DKS_CUDA=ON; "
                  "each frame's skeleton transforms are computed on the CPU)")
      ->check(CLI::IsMember({"cpu", "cuda"}))
      ->capture_default_str();
  sub->callback([args] { run_animate(*args); });
});

}  // namespace
