#include "fit/run_fit.hpp"

#include <filesystem>

#include "body/body_model.hpp"
#include "fit/fit_file.hpp"
#include "fit/overlay.hpp"
#include "io/image_io.hpp"

namespace ks {

namespace fs = std::filesystem;

FitResult run_fit(const std::string& subject_dir, const FitStageOptions& options) {
  const FitInput in = load_fit_input(subject_dir);
  const BodyModel model = load_body_model(options.body);
  const std::string model_name = options.body == "default"
                                     ? options.body
                                     : fs::absolute(options.body).lexically_normal().string();
  const FitResult r = fit_body(model, in, options.fit);
  const fs::path dir(subject_dir);
  if (options.overlay) {
    const Image photo = read_image((dir / "image.png").string(), 3);
    write_png((dir / "fit_overlay.png").string(),
              fit_overlay(photo, model, r.params, r.camera, in.keypoints, options.fit.keypoints));
  }
  std::string focal_from;
  fit_focal(options.fit, in, &focal_from);
  save_fit((dir / "fit.json").string(), model_name, r,
           {{"focal_from", focal_from},
            {"silhouette", options.fit.use_silhouette && !in.mask.empty()},
            {"keypoint_convention", to_string(options.fit.keypoints)}});
  return r;
}

}  // namespace ks
