#include "animate/playback.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <numeric>

#include "animate/framing.hpp"
#include "animate/posed_render.hpp"
#include "avatar/pose.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "core/progress.hpp"
#include "gaussians/ply.hpp"
#include "io/image_io.hpp"
#include "io/video.hpp"
#include "motion/motion.hpp"
#include "raster/rasterizer.hpp"
#include "raster_cuda/rasterizer_cuda.hpp"

namespace ks {

namespace fs = std::filesystem;

PlaybackReport render_playback(const Avatar& avatar, const std::string& out,
                               const PlaybackOptions& o) {
  if (o.width <= 0 || o.height <= 0 || o.width > 16384 || o.height > 16384)
    throw Error("playback: image size " + std::to_string(o.width) + "x" + std::to_string(o.height) +
                " out of range");
  if (o.frames < 0) throw Error("--frames must be >= 0");
  if (!(o.backface_cull >= 0.f && o.backface_cull <= 1.f))
    throw Error("--backface-cull: expected a cosine in [0, 1] (1 = off), got " +
                std::to_string(o.backface_cull));
  RasterSettings rs;
  std::copy(o.background, o.background + 3, rs.background);
  rs.image_only = true;
  const Motion motion = load_motion(o.motion, o.frames);
  if (motion.frames.empty()) throw Error("motion \"" + o.motion + "\" has no frames");
  const int F = int(motion.frames.size());
  Eigen::Vector3d lo, hi;
  motion_bounds(avatar, motion, lo, hi);
  const std::vector<Camera> cams = playback_cameras(o.camera, lo, hi, o.width, o.height, F);

  const bool mp4 = fs::path(out).extension() == ".mp4";
  if (mp4 && find_ffmpeg().empty())
    throw Error("writing " + out +
                " needs ffmpeg, which was not found on PATH (install it, e.g. `apt-get install "
                "ffmpeg`, or give a directory to get PNG frames)");
  // Frames go to a staging directory that appears only when complete.
  const std::string frame_dir =
      mp4 ? (fs::path(out).parent_path() / (fs::path(out).stem().string() + "_frames")).string()
          : out;
  if (!fs::path(frame_dir).parent_path().empty())
    fs::create_directories(fs::path(frame_dir).parent_path());
  StagedDir staged(frame_dir);
  if (o.progress)
    std::printf("animate: %d Gaussians, motion \"%s\" (%d frames at %.1f fps), camera %s, %dx%d\n",
                avatar.num_gaussians(), motion.name.c_str(), F, motion.fps, o.camera.c_str(),
                o.width, o.height);
  // Back-face culling needs the template's normals at the anchors; the per-frame .ply files
  // keep every Gaussian, so `ply` turns it off.
  const bool want_cull = o.backface_cull < 1.f && !o.ply;
  const std::vector<float> normals =
      want_cull ? avatar_anchor_normals(avatar) : std::vector<float>{};
  PlaybackReport rep;
  rep.culled = !normals.empty();
  if (want_cull && !rep.culled && o.progress)
    std::printf(
        "animate: the avatar's template is not one vertex per Gaussian; no back-face culling\n");
  BackfaceCull cull;
  cull.normals = &normals;
  cull.threshold = o.backface_cull;
  Gaussians g;  // the posed Gaussians, for the .ply files
  PosedRenderer renderer(avatar);
  std::unique_ptr<cuda::RasterizerCuda> gpu;
  if (o.cuda) gpu = std::make_unique<cuda::RasterizerCuda>();  // throws, saying why, without one
  RasterResult rr;
  Progress prog("animate", o.progress ? F : 0);
  std::vector<double> frame_ms;
  frame_ms.reserve(size_t(F));
  std::vector<std::string> pngs;
  for (int f = 0; f < F; ++f) {
    const auto t0 = std::chrono::steady_clock::now();
    cull.eye = cams[f].centre();
    // Posed as the projection reads them (the same image as posing first), unless the posed
    // Gaussians are written too: then posed once and rendered.
    if (gpu) {
      // Posed on the device: the canonical Gaussians and skin go once, then each frame's joint
      // transforms (and pose correctives' offsets, where the avatar has them).
      if (f == 0)
        gpu->upload_skinned(avatar.gaussians, avatar.skin_joints, avatar.skin_weights, normals);
      const AvatarPoseInputs in = avatar_pose_inputs(avatar, motion.frames[f]);
      gpu->pose(in.transforms, in.offsets.size() > 0 ? in.offsets.data() : nullptr,
                rep.culled ? &cull : nullptr);
      gpu->forward(cams[f], rs);
      gpu->download(rr, false);  // the frame's images only
      if (o.ply) gpu->download_gaussians(g);
    } else if (o.ply) {
      pose_avatar(avatar, motion.frames[f], g, nullptr, f > 0);
      rasterize_forward(g, cams[f], rs, rr);
    } else {
      renderer.render(motion.frames[f], cams[f], rs, rr, rep.culled ? &cull : nullptr);
    }
    frame_ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    char name[32];
    std::snprintf(name, sizeof name, "%04d", f);
    pngs.push_back(staged.path(std::string(name) + ".png"));
    write_png(pngs.back(), rr.color);
    if (o.ply) write_ply(staged.path(std::string(name) + ".ply"), g);
    if (o.progress) prog.update(f + 1);
  }
  if (o.progress) prog.finish();
  if (mp4) {
    VideoOptions vo;
    vo.fps = motion.fps;
    write_mp4_from_pngs(out, pngs, vo);
  }
  if (!mp4 || o.ply) {
    staged.commit();
    rep.frames_dir = frame_dir;
  }
  rep.frames = F;
  rep.fps = motion.fps;
  rep.render_ms = std::accumulate(frame_ms.begin(), frame_ms.end(), 0.0) / F;
  rep.render_max_ms = *std::max_element(frame_ms.begin(), frame_ms.end());
  std::sort(frame_ms.begin(), frame_ms.end());
  rep.render_median_ms = F % 2 ? frame_ms[size_t(F / 2)]
                               : 0.5 * (frame_ms[size_t(F / 2) - 1] + frame_ms[size_t(F / 2)]);
  return rep;
}

}  // namespace ks
