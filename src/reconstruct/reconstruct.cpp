#include "reconstruct/reconstruct.hpp"

#include <algorithm>
#include <memory>

#include "core/error.hpp"
#include "dataset/dataset.hpp"
#include "dataset/frames.hpp"
#include "reconstruct/density_ops.hpp"

namespace ks {

TrainReport reconstruct_avatar(const std::string& dataset_dir, const std::string& out,
                               const ReconstructOptions& options, Avatar* avatar) {
  TrainOptions opt = options.train;
  std::unique_ptr<DensityControl> control;
  opt.density_control = nullptr;
  opt.fine_frames = nullptr;
  require_density_name(options.density);
  const Dataset ds = Dataset::load(dataset_dir);
  const BodyModel model = load_dataset_body_model(ds, dataset_dir);
  const auto frames = load_frames(ds, dataset_dir, opt.scale, opt.perturb, opt.seed);
  std::vector<LoadedFrame> fine_frames;
  if (opt.fine_from < 1.f) {
    fine_frames = load_frames(ds, dataset_dir, opt.fine_scale, opt.perturb, opt.seed);
    opt.fine_frames = &fine_frames;
  }
  if (options.density != "off") {
    // Gradient thresholds are in training-image pixel units: pass the real training width.
    DensityOptions dopt;
    dopt.image_width = frames.empty() ? 0 : frames.front().image.width;
    control = make_density_control(options.density, dopt);
    opt.density_control = control.get();
  }
  TrainReport rep;
  Avatar av = train_avatar(model, ds, frames, opt, &rep);
  av.metadata["density"] = options.density;
  av.metadata["fine_scale"] = opt.fine_from < 1.f ? opt.fine_scale : opt.scale;
  save_avatar(out, av);
  if (avatar) *avatar = std::move(av);
  return rep;
}

}  // namespace ks
