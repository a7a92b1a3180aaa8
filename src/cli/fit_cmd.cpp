// `kinesplat fit`: body-model parameters and camera for a perceived subject; `kinesplat
// evaluate-fit`: a fit against a known truth (a synth subject.json).
#include <cstdio>
#include <filesystem>

#include "body/body_model.hpp"
#include "cli/registry.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "evaluate/fit_metrics.hpp"
#include "fit/fit.hpp"
#include "fit/fit_file.hpp"
#include "fit/keypoint_calibration.hpp"
#include "fit/overlay.hpp"
#include "fit/refine.hpp"
#include "fit/run_fit.hpp"
#include "io/image_io.hpp"
#include "perceive/openpose.hpp"

namespace {

namespace fs = std::filesystem;

ks::cli::CommandGroup group(24, [](CLI::App& app) {
  struct Args {
    ks::FitStageOptions so;
    std::string subject;
    bool no_silhouette = false, quiet = false;
    std::string refine_with;
    std::string keypoints = ks::to_string(so.fit.keypoints);
  };
  auto args = std::make_shared<Args>();
  auto* sub = app.add_subcommand(
      "fit", "Fit the body model and camera to a subject's keypoints and mask (SUBJECT/fit.json)");
  sub->add_option("subject", args->subject,
                  "Subject directory from `perceive` (image.png, mask.png, keypoints.json)")
      ->required();
  sub->add_option("--body", args->so.body, "Body model: 'default' or an SMPL / SMPL-X .npz")
      ->capture_default_str();
  sub->add_option("--focal", args->so.fit.focal,
                  "Focal length in pixels of image.png (default: the photo's EXIF focal as "
                  "perceive found it, else from --fov)");
  sub->add_option("--fov", args->so.fit.fov_degrees,
                  "Field of view across the image's long side, degrees, when --focal is not given")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 170.0));
  sub->add_option(
         "--keypoints", args->keypoints,
         "What the keypoints mark: 'coco' (where COCO-trained detectors and annotators put "
         "them: perceive's, OpenPose's, DWPose's) or 'joints' (the body model's joints: "
         "the synth's photo_keypoints.json)")
      ->capture_default_str()
      ->check(CLI::IsMember(ks::keypoint_convention_names()));
  sub->add_flag("--overlay", args->so.overlay,
                "Also write SUBJECT/fit_overlay.png (the body on the photo, keypoints)");
  sub->add_flag("--no-silhouette", args->no_silhouette, "Fit to the keypoints only");
  sub->add_option("--refine-with", args->refine_with,
                  "Refine SUBJECT/fit.json through this avatar's render instead of fitting: the "
                  "pose and global transform registered so that the render matches image.png "
                  "and mask.png (docs/register.md); the keypoint fit is kept as "
                  "SUBJECT/fit_keypoints.json")
      ->check(CLI::ExistingFile);
  sub->add_flag("--quiet,-q", args->quiet, "No stage lines");
  sub->callback([args] {
    if (!args->refine_with.empty()) {
      const ks::RefineFitResult r = ks::refine_fit(args->subject, args->refine_with);
      const ks::RegisterResult& g = r.registration;
      std::printf(
          "fit: registered through %s in %.1f s (%d steps): cost %.4f -> %.4f (mask %.4f -> "
          "%.4f)%s; wrote %s (keypoint fit in %s)\n",
          args->refine_with.c_str(), g.seconds, g.steps, g.cost_before, g.cost_after, g.mask_before,
          g.mask_after, g.improved ? "" : ", no improvement: the pose is kept", r.fit_path.c_str(),
          r.keypoint_fit_path.c_str());
      return;
    }
    ks::FitStageOptions so = args->so;
    so.fit.use_silhouette = !args->no_silhouette;
    so.fit.progress = !args->quiet;
    so.fit.keypoints = ks::parse_keypoint_convention(args->keypoints);
    const ks::FitResult r = ks::run_fit(args->subject, so);
    std::printf("fit: %s the camera, focal %.1f px, %.1f s; wrote %s\n",
                r.facing_camera ? "facing" : "turned away from", r.camera.fx, r.seconds,
                (fs::path(args->subject) / "fit.json").string().c_str());
  });

  struct EvalArgs {
    std::string fit, truth, out, renders;
  };
  auto ea = std::make_shared<EvalArgs>();
  auto* ev = app.add_subcommand(
      "evaluate-fit",
      "Compare a fit.json with a known truth (e.g. a synth subject.json): MPJPE, PA-MPJPE of the "
      "joints (mm), IoU of the bodies' silhouettes");
  ev->add_option("fit", ea->fit, "fit.json")->required();
  ev->add_option("truth", ea->truth, "The truth in the same layout (subject.json from synth)")
      ->required();
  ev->add_option("--out", ea->out, "Also write the figures as JSON");
  ev->add_option("--renders", ea->renders,
                 "Also write front.png and side.png (pelvis aligned) and image.png (each body "
                 "through its own camera) into this directory: the truth's body in green, the "
                 "fit's in red");
  ev->callback([ea] {
    const ks::SubjectFit est = ks::load_fit(ea->fit);
    const ks::SubjectFit truth = ks::load_fit(ea->truth);
    const ks::FitMetrics m = ks::evaluate_fit(est, truth);
    const nlohmann::json j = m.to_json();
    if (!ea->out.empty()) ks::write_json_atomic(ea->out, j);
    if (!ea->renders.empty()) {
      fs::create_directories(ea->renders);
      ks::write_png((fs::path(ea->renders) / "front.png").string(),
                    ks::fit_comparison_view(est, truth, 0));
      ks::write_png((fs::path(ea->renders) / "side.png").string(),
                    ks::fit_comparison_view(est, truth, 1));
      ks::write_png((fs::path(ea->renders) / "image.png").string(),
                    ks::fit_comparison_view(est, truth, 2));
    }
    std::printf("%s\n", j.dump(1).c_str());
  });

  // A developer's tool: the keypoint convention's offsets from the joints, measured.
  auto files = std::make_shared<std::vector<std::string>>();
  auto* cal = app.add_subcommand(
      "calibrate-keypoints",
      "Measure where detected keypoints sit relative to the body's joints, from pairs TRUTH.json "
      "KEYPOINTS.json (a synth subject.json and the keypoints perceive found on its photo); "
      "prints the offsets of body/keypoints.cpp's COCO convention (docs/fit.md)");
  cal->add_option("pairs", *files, "TRUTH.json KEYPOINTS.json [TRUTH.json KEYPOINTS.json ...]")
      ->required();
  cal->callback([files] {
    if (files->size() % 2)
      throw ks::Error("calibrate-keypoints: give TRUTH.json KEYPOINTS.json pairs");
    std::vector<ks::CalibrationSample> samples;
    for (size_t i = 0; i < files->size(); i += 2) {
      ks::CalibrationSample s;
      s.truth = ks::load_fit((*files)[i]);
      ks::KeypointReadOptions ko;
      ko.pixel_centre = 0.5;
      const ks::KeypointFile kf = ks::read_keypoints((*files)[i + 1], ko);
      s.detected = ks::fit_keypoints(kf.person);
      samples.push_back(std::move(s));
    }
    const ks::KeypointCalibration c = ks::calibrate_keypoints(samples);
    std::printf("keypoint      offset x, y, z (m)          n   mean px before -> after\n");
    for (int k = 0; k < ks::kBody25Count; ++k)
      if (c.samples[size_t(k)] > 0)
        std::printf("%-10s  % .4f % .4f % .4f  %4d   %6.2f -> %6.2f\n",
                    ks::body25_names()[size_t(k)], c.offset[size_t(k)].x(), c.offset[size_t(k)].y(),
                    c.offset[size_t(k)].z(), c.samples[size_t(k)], c.before_px[size_t(k)],
                    c.after_px[size_t(k)]);
  });
});

}  // namespace
