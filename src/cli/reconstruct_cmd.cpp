// `kinesplat reconstruct DATASET --out AVATAR`: the avatar fit (docs/reconstruct.md).
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "avatar/avatar.hpp"
#include "cli/registry.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "dataset/dataset.hpp"
#include "evaluate/evaluate.hpp"
#include "raster_cuda/rasterizer_cuda.hpp"
#include "reconstruct/density.hpp"
#include "reconstruct/reconstruct.hpp"
#include "reconstruct/trainer.hpp"

namespace {

const char* garment_name(ks::GarmentMode m) {
  return m == ks::GarmentMode::kNone ? "none" : m == ks::GarmentMode::kSkirt ? "skirt" : "auto";
}

const char* laplacian_name(ks::LaplacianMode m) {
  return m == ks::LaplacianMode::kSemantic  ? "semantic"
         : m == ks::LaplacianMode::kUniform ? "uniform"
                                            : "none";
}

// The library's TrainOptions hold the defaults; the flags only override them.
struct Args {
  ks::ReconstructOptions ro;
  ks::TrainOptions& opt = ro.train;
  std::string& density = ro.density;
  std::string dataset, out, eval_dataset, eval_out;
  std::string laplacian = laplacian_name(opt.loss.laplacian);
  std::string garment = garment_name(opt.garment.mode);
  bool quiet = false;
  float eval_scale = 1.f;
  std::string device = opt.cuda_raster ? "cuda" : "cpu";
};

ks::cli::CommandGroup group(40, [](CLI::App& app) {
  auto args = std::make_shared<Args>();
  auto* sub = app.add_subcommand("reconstruct", "Fit an animatable Gaussian avatar to a dataset");
  sub->add_option("dataset", args->dataset, "Dataset directory (dataset.json + images)")
      ->required();
  sub->add_option("--out,-o", args->out, "Output avatar file (.ksavatar)")->required();
  sub->add_option("--iters", args->opt.iterations, "Optimisation steps")->capture_default_str();
  sub->add_option("--scale", args->opt.scale, "Training resolution relative to the images")
      ->capture_default_str();
  sub->add_option("--fine-from", args->opt.fine_from,
                  "Coarse-to-fine: from this fraction of the iterations on, train at --fine-scale "
                  "(1 = never)")
      ->capture_default_str();
  auto* fine_scale = sub->add_option("--fine-scale", args->opt.fine_scale,
                                     "Resolution of the fine phase (with --fine-from < 1)")
                         ->capture_default_str();
  sub->add_option("--filter3d", args->opt.decoder.filter3d,
                  "3D smoothing filter variance in training pixels^2 (0 = off)")
      ->capture_default_str();
  sub->add_option("--subdivide", args->opt.subdivide, "Loop subdivision levels of the template")
      ->capture_default_str();
  sub->add_option("--laplacian", args->laplacian, "Laplacian regulariser: semantic|uniform|none")
      ->capture_default_str();
  sub->add_option("--density", args->density, "Density control: gpdc|vertex|naive|off")
      ->capture_default_str();
  sub->add_option("--garment", args->garment,
                  "Garment layer: none|skirt|auto (auto: a skirt proxy when the masks show cloth "
                  "spanning the legs)")
      ->capture_default_str();
  sub->add_option("--garment-hem", args->opt.garment.skirt.hem,
                  "Skirt hem (--garment skirt): fraction of the way from hips to knees")
      ->capture_default_str();
  sub->add_option("--garment-follow", args->opt.garment.skirt.follow,
                  "How much the skirt's hem follows the legs (0 = pelvis only)")
      ->capture_default_str();
  sub->add_option("--garment-spacing", args->opt.garment.skirt.spacing,
                  "Metres between the skirt proxy's vertices (0 = 1.25 x the template's mean edge)")
      ->capture_default_str();
  sub->add_option("--garment-wrap", args->opt.garment.skirt.wrap,
                  "Blend the body's skinning into the skirt's above the crotch (0/1)")
      ->capture_default_str();
  sub->add_option("--garment-follow-knots", args->opt.garment.skirt.follow_knots,
                  "The follow as a profile of this many values from rim to hem (1 = one number)")
      ->check(CLI::Range(1, 16))
      ->capture_default_str();
  sub->add_option("--garment-margin", args->opt.garment.skirt.margin,
                  "Metres the skirt proxy stands outside the hips' and thighs' cross-section")
      ->check(CLI::Range(0.0, 0.2))
      ->capture_default_str();
  sub->add_option("--garment-waist", args->opt.garment.skirt.waist,
                  "Metres below the rim over which the body under the skirt blends from its own "
                  "skinning to the skirt's (0 = none)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  sub->add_option("--garment-fit-width", args->opt.garment.fit_width,
                  "--garment auto: widen the skirt proxy to the width the masks show (0/1)")
      ->capture_default_str();
  sub->add_option("--visibility", args->opt.visibility.enabled,
                  "Decode and draw only the Gaussians a training frame can see (a depth test "
                  "against the last decode's centres), from --visibility-start on: faster "
                  "steps, a little less full-frame PSNR")
      ->capture_default_str();
  sub->add_option("--visibility-start", args->opt.visibility.start,
                  "Fraction of the iterations decoded whole first (with --visibility)")
      ->capture_default_str();
  sub->add_option("--visibility-whole-every", args->opt.visibility.whole_every,
                  "With --visibility, every this many steps still decodes and draws every "
                  "Gaussian (0 = never, 1 = always)")
      ->capture_default_str();
  sub->add_option("--visibility-footprint", args->opt.visibility.footprint,
                  "With --visibility, compare each Gaussian with the cells its footprint covers "
                  "(hides fewer)")
      ->capture_default_str();
  sub->add_option("--visibility-margin", args->opt.visibility.depth_margin,
                  "Metres behind the nearest surface around it before a Gaussian is hidden")
      ->capture_default_str();
  sub->add_option("--lr-garment-follow", args->opt.garment.lr_follow,
                  "Learning rate of the skirt's follow (logit units; 0 = fixed)")
      ->capture_default_str();
  sub->add_flag("--perturb", args->opt.perturb.enabled,
                "Imperfect prior: colour drift, pose jitter and small warps per frame");
  sub->add_option("--seed", args->opt.seed, "Random seed")->capture_default_str();
  sub->add_option("--w-l1", args->opt.loss.w_l1, "Weight of the L1 image loss")
      ->capture_default_str();
  sub->add_option("--w-ssim", args->opt.loss.w_ssim, "Weight of 1 - SSIM")->capture_default_str();
  sub->add_option("--w-mask", args->opt.loss.w_mask, "Weight of the mask loss")
      ->capture_default_str();
  sub->add_option("--w-offset", args->opt.loss.w_offset, "Weight of the offset L2")
      ->capture_default_str();
  sub->add_option("--w-lap-pos", args->opt.loss.w_lap_position, "Weight of the position Laplacian")
      ->capture_default_str();
  sub->add_option("--w-lap-color", args->opt.loss.w_lap_color, "Weight of the colour Laplacian")
      ->capture_default_str();
  sub->add_option("--lr-triplane", args->opt.optimizer.lr_triplane, "Triplane learning rate")
      ->capture_default_str();
  sub->add_option("--lr-mlp", args->opt.optimizer.lr_mlp, "MLP learning rate")
      ->capture_default_str();
  sub->add_option("--lr-vertex-color", args->opt.vertex_color.lr,
                  "Learning rate of a per-Gaussian colour residual on top of the decoder (0 = off)")
      ->capture_default_str();
  sub->add_option("--lr-skin", args->opt.skin.lr,
                  "Learning rate of the learned skin weights (softmax logits; 0 = the body's "
                  "weights, fixed)")
      ->capture_default_str();
  sub->add_option("--skin-from", args->opt.skin.from,
                  "Learn the skin weights from this fraction of the iterations on")
      ->capture_default_str();
  sub->add_option("--w-skin-prior", args->opt.skin.w_prior,
                  "Weight of the pull of learned skin weights towards the body's")
      ->capture_default_str();
  sub->add_option("--w-lap-skin", args->opt.skin.w_laplacian,
                  "Weight of the Laplacian smoothness of learned skin weights")
      ->capture_default_str();
  sub->add_option("--triplane-res", args->opt.decoder.triplane_res, "Triplane resolution")
      ->capture_default_str();
  sub->add_option("--triplane-channels", args->opt.decoder.triplane_channels,
                  "Feature channels of each triplane plane (the decoders read 3x this many)")
      ->capture_default_str();
  sub->add_option("--joint-decoder", args->opt.decoder.joint,
                  "One decoder MLP for geometry and colour instead of two")
      ->capture_default_str();
  sub->add_option("--hidden", args->opt.decoder.hidden, "Hidden width of the decoder MLPs")
      ->capture_default_str();
  sub->add_option("--max-offset", args->opt.decoder.max_offset,
                  "Largest offset from the template (m)")
      ->capture_default_str();
  sub->add_option("--log-every", args->opt.log_every, "Print the losses every N iterations")
      ->capture_default_str();
  sub->add_option("--eval", args->eval_dataset,
                  "After training, evaluate on this dataset (e.g. the test split)");
  auto* eval_out = sub->add_option("--eval-out", args->eval_out,
                                   "Write the evaluation metrics JSON here (with --eval)");
  auto* eval_scale = sub->add_option("--eval-scale", args->eval_scale,
                                     "Evaluation resolution relative to images (with --eval)")
                         ->capture_default_str();
  sub->add_option("--device", args->device,
                  "cpu, or cuda: the rasterizer's forward and backward on an NVIDIA GPU (a build "
                  "with -DKS_CUDA=ON); the rest of each step stays on the CPU")
      ->check(CLI::IsMember({"cpu", "cuda"}))
      ->capture_default_str();
  sub->add_flag("--quiet,-q", args->quiet, "No progress bar");
  sub->callback([args, sub, fine_scale, eval_out, eval_scale] {
    Args& a = *args;
    a.opt.cuda_raster = a.device == "cuda";
    if (a.opt.cuda_raster && ks::cuda::raster_cuda_devices() == 0)
      throw ks::Error("--device cuda: " + ks::cuda::raster_cuda_describe());
    // Options that would be silently ignored in this combination.
    if (a.eval_dataset.empty() && (eval_out->count() > 0 || eval_scale->count() > 0))
      throw ks::Error(std::string(eval_out->count() > 0 ? "--eval-out" : "--eval-scale") +
                      " needs --eval DATASET (there is nothing to evaluate without it)");
    if (fine_scale->count() > 0 && !(a.opt.fine_from < 1.f))
      throw ks::Error(
          "--fine-scale needs --fine-from < 1 (without it every step trains at --scale)");
    a.opt.loss.laplacian = ks::parse_laplacian_mode(a.laplacian);
    if (a.garment == "none")
      a.opt.garment.mode = ks::GarmentMode::kNone;
    else if (a.garment == "skirt")
      a.opt.garment.mode = ks::GarmentMode::kSkirt;
    else if (a.garment == "auto")
      a.opt.garment.mode = ks::GarmentMode::kAuto;
    else
      throw ks::Error("--garment " + a.garment + ": expected none, skirt or auto");
    if (a.opt.garment.mode == ks::GarmentMode::kNone)
      for (const char* o : {"--garment-hem", "--garment-follow", "--garment-spacing",
                            "--garment-wrap", "--garment-follow-knots", "--garment-margin",
                            "--garment-waist", "--garment-fit-width", "--lr-garment-follow"})
        if (sub->count(o) > 0)
          throw ks::Error(std::string(o) + " has no effect with --garment none");
    if (a.opt.skin.lr > 0 && sub->count("--lr-garment-follow") > 0 && a.opt.garment.lr_follow > 0)
      std::fprintf(stderr,
                   "reconstruct: --lr-garment-follow is not used with --lr-skin > 0 (the learned "
                   "skin weights own the skirt's skinning then)\n");
    if (!(a.opt.skin.lr > 0))
      for (const char* o : {"--skin-from", "--w-skin-prior", "--w-lap-skin"})
        if (sub->count(o) > 0) throw ks::Error(std::string(o) + " needs --lr-skin > 0");
    a.opt.progress = !a.quiet;
    ks::Avatar av;
    const ks::TrainReport rep = ks::reconstruct_avatar(a.dataset, a.out, a.ro, &av);
    if (!rep.garment_summary.empty())
      std::printf("%s%s\n", rep.garment_summary.c_str(),
                  rep.garment ? ("; follow " + rep.garment_follow_profile).c_str() : "");
    std::printf("avatar: %s (%d Gaussians)\n", a.out.c_str(), av.num_gaussians());
    std::printf("train: %d iterations in %.1f s (%.1f ms/iteration), train PSNR %.2f dB\n",
                rep.iterations, rep.seconds, rep.ms_per_iteration, rep.final_psnr);
    if (rep.visible_steps > 0)
      std::printf(
          "visibility: %d steps decoded only what their frame sees (%.0f %% of the "
          "Gaussians on average)\n",
          rep.visible_steps, 100.0 * rep.visible_share);
    if (!a.eval_dataset.empty()) {
      const ks::Dataset test = ks::Dataset::load(a.eval_dataset);
      const ks::EvalReport er =
          ks::evaluate_avatar(av, test, a.eval_dataset, a.eval_scale, "", !a.quiet);
      nlohmann::json j = er.to_json(test);
      j["train"] = {{"iterations", rep.iterations},
                    {"seconds", rep.seconds},
                    {"ms_per_iteration", rep.ms_per_iteration},
                    {"num_gaussians", rep.num_gaussians}};
      if (!a.eval_out.empty()) ks::write_json_atomic(a.eval_out, j);
      std::printf("eval: PSNR %.2f SSIM %.4f | masked PSNR %.2f SSIM %.4f (%zu frames)\n",
                  er.mean.psnr, er.mean.ssim, er.mean.psnr_masked, er.mean.ssim_masked,
                  er.frames.size());
    }
  });
});

}  // namespace
