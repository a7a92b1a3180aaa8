// `kinesplat evaluate AVATAR DATASET --out metrics.json`: PSNR / SSIM of the posed avatar against
// every frame of a dataset, full frame (on the dataset's background) and inside the mask.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include <Eigen/Geometry>
#include "avatar/avatar.hpp"
#include "cli/registry.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "dataset/dataset.hpp"

#include "evaluate/alignment.hpp"
#include "evaluate/evaluate.hpp"

namespace {

struct Args {
  std::string avatar, dataset, out, renders, fit, truth;
  float scale = 1.f;
  bool quiet = false, reg = false;
};

ks::cli::CommandGroup group(50, [](CLI::App& app) {
  auto args = std::make_shared<Args>();
  auto* sub = app.add_subcommand("evaluate", "PSNR / SSIM of an avatar against a dataset");
  sub->add_option("avatar", args->avatar, "Avatar file")->required();
  sub->add_option("dataset", args->dataset, "Dataset directory with ground-truth frames")
      ->required();
  sub->add_option("--out,-o", args->out, "Metrics JSON (per frame and mean)");
  sub->add_option("--renders", args->renders, "Also write the renders (PNG) into this directory");
  sub->add_option("--scale", args->scale, "Resolution relative to the dataset's images")
      ->capture_default_str();
  auto* fit = sub->add_option("--fit", args->fit,
                              "With --truth: the fit.json the avatar was made from (photo only): "
                              "the dataset's frames are aligned to the avatar's frame first "
                              "(docs/evaluate.md)");
  auto* truth = sub->add_option("--truth", args->truth,
                                "With --fit: the truth's fit in the dataset's frame (the synth's "
                                "subject.json)");
  fit->needs(truth);
  truth->needs(fit);
  sub->add_flag("--register", args->reg,
                "Also measure each frame after registering its pose to the frame (the avatar "
                "fixed: pose and global transform optimised so that the render matches the "
                "image; docs/register.md), beside the plain figures");
  sub->add_flag("--quiet,-q", args->quiet, "No progress bar");
  sub->callback([args] {
    const ks::Avatar av = ks::load_avatar(args->avatar);
    ks::Dataset ds = ks::Dataset::load(args->dataset);
    if (!args->fit.empty()) {
      const ks::SubjectFit fit = ks::load_fit(args->fit), truth = ks::load_fit(args->truth);
      const ks::Similarity sim = ks::fit_alignment(fit, truth);
      ds = ks::align_dataset(ds, sim, truth, av.rest_joints.row(0).transpose());
      std::printf("aligned: scale %.4f, rotation %.2f degrees, translation %.3f m\n", sim.s,
                  Eigen::AngleAxisd(sim.R).angle() * 180.0 / M_PI, sim.t.norm());
    }
    if (!args->renders.empty()) std::filesystem::create_directories(args->renders);
    const ks::RegisterOptions ro;
    const ks::EvalReport rep = ks::evaluate_avatar(
        av, ds, args->dataset, args->scale, args->renders, !args->quiet, args->reg ? &ro : nullptr);
    const nlohmann::json j = rep.to_json(ds);
    if (!args->out.empty()) ks::write_json_atomic(args->out, j);
    for (size_t i = 0; i < rep.frames.size(); ++i) {
      std::printf("frame %zu: PSNR %.2f SSIM %.4f | masked PSNR %.2f SSIM %.4f", i,
                  rep.frames[i].psnr, rep.frames[i].ssim, rep.frames[i].psnr_masked,
                  rep.frames[i].ssim_masked);
      if (rep.registered_run)
        std::printf(" | registered: masked PSNR %.2f SSIM %.4f",
                    rep.registered.frames[i].psnr_masked, rep.registered.frames[i].ssim_masked);
      std::printf("\n");
    }
    auto summary = [](const ks::EvalFigures& f, const char* prefix) {
      std::printf(
          "%smean PSNR %.3f\n%smean SSIM %.4f\n%smean masked PSNR %.3f\n%smean masked SSIM "
          "%.4f\n",
          prefix, f.mean.psnr, prefix, f.mean.ssim, prefix, f.mean.psnr_masked, prefix,
          f.mean.ssim_masked);
      static const char* kViews[3] = {"front", "side", "back"};
      for (int v = 0; v < 3; ++v)
        if (f.view_frames[v] > 0)
          std::printf("%s%s (%d frames): PSNR %.3f SSIM %.4f | masked PSNR %.3f SSIM %.4f\n",
                      prefix, kViews[v], f.view_frames[v], f.by_view[v].psnr, f.by_view[v].ssim,
                      f.by_view[v].psnr_masked, f.by_view[v].ssim_masked);
    };
    summary(rep, "");
    if (rep.registered_run) {
      summary(rep.registered, "registered: ");
      std::printf("registered: %.0f ms per frame\n", rep.ms_per_register);
    }
  });
});

}  // namespace
