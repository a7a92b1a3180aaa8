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

void EvalFigures::add(const ImageMetrics& m, int v) {
  frames.push_back(m);
  ImageMetrics& g = by_view[v];
  g.psnr += m.psnr;
  g.ssim += m.ssim;
  g.psnr_masked += std::isnan(m.psnr_masked) ? 0 : m.psnr_masked;
  g.ssim_masked += std::isnan(m.ssim_masked) ? 0 : m.ssim_masked;
  ++view_frames[v];
  mean.psnr += m.psnr;
  mean.ssim += m.ssim;
  if (!std::isnan(m.psnr_masked)) {
    mean.psnr_masked += m.psnr_masked;
    mean.ssim_masked += m.ssim_masked;
    ++masked_frames;
  }
}

void EvalFigures::finish() {
  const double nf = double(std::max<size_t>(1, frames.size()));
  mean.psnr /= nf;
  mean.ssim /= nf;
  mean.psnr_masked = masked_frames ? mean.psnr_masked / masked_frames : NAN;
  mean.ssim_masked = masked_frames ? mean.ssim_masked / masked_frames : NAN;
  for (int v = 0; v < 3; ++v) {
    const double n = std::max(1, view_frames[v]);
    by_view[v].psnr /= n;
    by_view[v].ssim /= n;
    by_view[v].psnr_masked /= n;
    by_view[v].ssim_masked /= n;
  }
}

EvalReport evaluate_avatar(const Avatar& avatar, const Dataset& ds, const std::string& dir,
                           float scale, const std::string& render_dir, bool show_progress,
                           const RegisterOptions* registration) {
  if (ds.frames.empty()) throw Error("evaluate: dataset " + dir + " has no frames");
  if (!(scale > 0.f && scale <= 4.f)) throw Error("evaluate: scale must be in (0, 4]");
  EvalReport rep;
  rep.registered_run = registration != nullptr;
  RasterSettings rs;
  for (int k = 0; k < 3; ++k) rs.background[k] = ds.background[k];
  rs.image_only = true;
  RasterResult rr;
  Gaussians posed;
  Progress progress(registration ? "evaluate + register" : "evaluate", long(ds.frames.size()));
  double render_s = 0, register_s = 0;
  auto write = [&](const char* stem, size_t i) {
    if (render_dir.empty()) return;
    char name[64];
    std::snprintf(name, sizeof name, "%s_%04zu.png", stem, i);
    write_png((std::filesystem::path(render_dir) / name).string(), rr.color);
  };
  for (size_t i = 0; i < ds.frames.size(); ++i) {
    const LoadedFrame fr = load_frame(ds, dir, i, scale);
    const auto t0 = std::chrono::steady_clock::now();
    pose_avatar(avatar, fr.pose, posed, nullptr, i > 0);
    rasterize_forward(posed, fr.camera, rs, rr);
    render_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    int v;
    {
      const Eigen::Vector3d fwd =
          axis_angle_to_matrix<double>(Eigen::Vector3d(fr.pose.global_orient)) *
          Eigen::Vector3d::UnitZ();
      const Eigen::Vector3d root = avatar_posed_joints(avatar, fr.pose).row(0).transpose();
      const Eigen::Vector3d to_cam = (fr.camera.centre() - root).normalized();
      const double c = fwd.normalized().dot(to_cam);
      v = c > std::cos(M_PI / 4) ? 0 : c < -std::cos(M_PI / 4) ? 2 : 1;
      static const char* kNames[3] = {"front", "side", "back"};
      rep.view.push_back(kNames[v]);
    }
    rep.add(compute_metrics(rr.color, fr.image, fr.mask), v);
    write("render", i);
    if (registration) {
      // The view is the unregistered pose's, so that both sets of figures average the same frames.
      RegisterResult r = register_pose(avatar, fr.pose, fr.camera, fr.image, fr.mask, ds.background,
                                       *registration);
      register_s += r.seconds;
      pose_avatar(avatar, r.params, posed, nullptr, true);
      rasterize_forward(posed, fr.camera, rs, rr);
      rep.registered.add(compute_metrics(rr.color, fr.image, fr.mask), v);
      rep.registration.push_back(std::move(r));
      write("registered", i);
    }
    if (show_progress) progress.update(long(i + 1));
  }
  if (show_progress) progress.finish();
  rep.finish();
  if (registration) rep.registered.finish();
  const double nf = double(ds.frames.size());
  rep.ms_per_render = 1000.0 * render_s / nf;
  rep.ms_per_register = 1000.0 * register_s / nf;
  return rep;
}

namespace {

nlohmann::json num(double v) {
  if (std::isnan(v)) return nullptr;
  if (std::isinf(v)) return 1e9;
  return v;
}

nlohmann::json metrics_json(const ImageMetrics& m) {
  return {{"psnr", num(m.psnr)},
          {"ssim", num(m.ssim)},
          {"psnr_masked", num(m.psnr_masked)},
          {"ssim_masked", num(m.ssim_masked)}};
}

// frames (with `extra` per frame where given), mean and by_view.
void figures_json(const EvalFigures& f, const Dataset& ds, const std::vector<std::string>& view,
                  nlohmann::json& j, const std::vector<nlohmann::json>& extra = {}) {
  nlohmann::json arr = nlohmann::json::array();
  for (size_t i = 0; i < f.frames.size(); ++i) {
    nlohmann::json e = {{"frame", i},
                        {"image", i < ds.frames.size() ? ds.frames[i].image : ""},
                        {"view", i < view.size() ? view[i] : ""}};
    e.update(metrics_json(f.frames[i]));
    if (i < extra.size()) e.update(extra[i]);
    arr.push_back(e);
  }
  j["frames"] = arr;
  j["mean"] = metrics_json(f.mean);
  static const char* kNames[3] = {"front", "side", "back"};
  for (int v = 0; v < 3; ++v)
    if (f.view_frames[v] > 0) {
      j["by_view"][kNames[v]] = metrics_json(f.by_view[v]);
      j["by_view"][kNames[v]]["frames"] = f.view_frames[v];
    }
}

}  // namespace

nlohmann::json EvalReport::to_json(const Dataset& ds) const {
  nlohmann::json j;
  figures_json(*this, ds, view, j);
  j["num_frames"] = frames.size();
  j["ms_per_render"] = ms_per_render;
  if (registered_run) {
    std::vector<nlohmann::json> extra;
    for (const RegisterResult& r : registration)
      extra.push_back({{"registration",
                        {{"improved", r.improved},
                         {"cost_before", r.cost_before},
                         {"cost_after", r.cost_after},
                         {"mask_before", r.mask_before},
                         {"mask_after", r.mask_after},
                         {"steps", r.steps},
                         {"seconds", r.seconds}}}});
    nlohmann::json reg;
    figures_json(registered, ds, view, reg, extra);
    reg["ms_per_register"] = ms_per_register;
    j["registered"] = reg;
  }
  return j;
}

}  // namespace ks
