#include "evaluate/evaluate.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "avatar/pose.hpp"
#include "core/error.hpp"
#include "core/progress.hpp"
#include "core/rotation.hpp"
#include "dataset/frames.hpp"
#include "io/image_io.hpp"
#include "raster/rasterizer.hpp"

namespace ks {

EvalReport evaluate_avatar(const Avatar& avatar, const Dataset& ds, const std::string& dir,
                           float scale, const std::string& render_dir, bool show_progress) {
  if (ds.frames.empty()) throw Error("evaluate: dataset " + dir + " has no frames");
  if (!(scale > 0.f && scale <= 4.f)) throw Error("evaluate: scale must be in (0, 4]");
  EvalReport rep;
  RasterSettings rs;
  for (int k = 0; k < 3; ++k) rs.background[k] = ds.background[k];
  rs.image_only = true;
  RasterResult rr;
  Gaussians posed;
  Progress progress("evaluate", long(ds.frames.size()));
  double render_s = 0;
  int masked_frames = 0;
  for (size_t i = 0; i < ds.frames.size(); ++i) {
    const LoadedFrame fr = load_frame(ds, dir, i, scale);
    const auto t0 = std::chrono::steady_clock::now();
    pose_avatar(avatar, fr.pose, posed, nullptr, i > 0);
    rasterize_forward(posed, fr.camera, rs, rr);
    render_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const ImageMetrics m = compute_metrics(rr.color, fr.image, fr.mask);
    rep.frames.push_back(m);
    {
      const Eigen::Vector3d fwd =
          axis_angle_to_matrix<double>(Eigen::Vector3d(fr.pose.global_orient)) *
          Eigen::Vector3d::UnitZ();
      const Eigen::Vector3d root = avatar_posed_joints(avatar, fr.pose).row(0).transpose();
      const Eigen::Vector3d to_cam = (fr.camera.centre() - root).normalized();
      const double c = fwd.normalized().dot(to_cam);
      const int v = c > std::cos(M_PI / 4) ? 0 : c < -std::cos(M_PI / 4) ? 2 : 1;
      static const char* kNames[3] = {"front", "side", "back"};
      rep.view.push_back(kNames[v]);
      ImageMetrics& g = rep.by_view[v];
      g.psnr += m.psnr;
      g.ssim += m.ssim;
      g.psnr_masked += std::isnan(m.psnr_masked) ? 0 : m.psnr_masked;
      g.ssim_masked += std::isnan(m.ssim_masked) ? 0 : m.ssim_masked;
      ++rep.view_frames[v];
    }
    rep.mean.psnr += m.psnr;
    rep.mean.ssim += m.ssim;
    if (!std::isnan(m.psnr_masked)) {
      rep.mean.psnr_masked += m.psnr_masked;
      rep.mean.ssim_masked += m.ssim_masked;
      ++masked_frames;
    }
    if (!render_dir.empty()) {
      char name[64];
      std::snprintf(name, sizeof name, "render_%04zu.png", i);
      write_png((std::filesystem::path(render_dir) / name).string(), rr.color);
    }
    if (show_progress) progress.update(long(i + 1));
  }
  if (show_progress) progress.finish();
  const double nf = double(ds.frames.size());
  rep.mean.psnr /= nf;
  rep.mean.ssim /= nf;
  rep.mean.psnr_masked = masked_frames ? rep.mean.psnr_masked / masked_frames : NAN;
  rep.mean.ssim_masked = masked_frames ? rep.mean.ssim_masked / masked_frames : NAN;
  rep.ms_per_render = 1000.0 * render_s / nf;
  for (int v = 0; v < 3; ++v) {
    const double n = std::max(1, rep.view_frames[v]);
    rep.by_view[v].psnr /= n;
    rep.by_view[v].ssim /= n;
    rep.by_view[v].psnr_masked /= n;
    rep.by_view[v].ssim_masked /= n;
  }
  return rep;
}

nlohmann::json EvalReport::to_json(const Dataset& ds) const {
  auto num = [](double v) -> nlohmann::json {
    if (std::isnan(v)) return nullptr;
    if (std::isinf(v)) return 1e9;
    return v;
  };
  nlohmann::json j;
  nlohmann::json arr = nlohmann::json::array();
  for (size_t i = 0; i < frames.size(); ++i) {
    const auto& m = frames[i];
    arr.push_back({{"frame", i},
                   {"image", i < ds.frames.size() ? ds.frames[i].image : ""},
                   {"view", i < view.size() ? view[i] : ""},
                   {"psnr", num(m.psnr)},
                   {"ssim", num(m.ssim)},
                   {"psnr_masked", num(m.psnr_masked)},
                   {"ssim_masked", num(m.ssim_masked)}});
  }
  j["frames"] = arr;
  j["mean"] = {{"psnr", num(mean.psnr)},
               {"ssim", num(mean.ssim)},
               {"psnr_masked", num(mean.psnr_masked)},
               {"ssim_masked", num(mean.ssim_masked)}};
  static const char* kNames[3] = {"front", "side", "back"};
  for (int v = 0; v < 3; ++v)
    if (view_frames[v] > 0)
      j["by_view"][kNames[v]] = {{"frames", view_frames[v]},
                                 {"psnr", num(by_view[v].psnr)},
                                 {"ssim", num(by_view[v].ssim)},
                                 {"psnr_masked", num(by_view[v].psnr_masked)},
                                 {"ssim_masked", num(by_view[v].ssim_masked)}};
  j["num_frames"] = frames.size();
  j["ms_per_render"] = ms_per_render;
  return j;
}

}  // namespace ks
