#pragma once
// SUBJECT/fit.json: the body model, its shape, the body parameters (the project's params JSON),
// the camera (the project's camera JSON) and each fit term's final cost. Later stages accept a
// fit.json written by another tool as long as it has these fields. Documented in docs/fit.md.
#include <array>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "body/body_model.hpp"
#include "core/camera.hpp"
#include "fit/fit.hpp"
#include "perceive/openpose.hpp"

namespace ks {

struct SubjectFit {
  std::string body_model = "default";  // as written: "default" or a path
  std::shared_ptr<const BodyModel> model;
  BodyParams params;  // betas included
  Camera camera;
  nlohmann::json costs;  // may be empty
};

// Writes fit.json (atomically). `body_model` is the name to record ("default" or a path).
void save_fit(const std::string& path, const std::string& body_model, const FitResult& result,
              const nlohmann::json& extra = {});

// Reads a fit.json: "body_model" (default "default"; a relative path is taken relative to the
// file's directory first), "params" (or "pose", as the synth's subject.json has it), "betas" (top
// level or in the params), "camera". Loads the body model. Throws ks::Error naming the file and
// the problem.
SubjectFit load_fit(const std::string& path);

// A keypoint file's chosen person as the fit reads keypoints: (x, y, confidence) in pixels, zero
// where a keypoint is absent.
std::array<Eigen::Vector3d, kBody25Count> fit_keypoints(const PersonKeypoints& person);

// The inputs of the fit from a subject directory: image.png (for its size), mask.png (optional)
// and keypoints.json (OpenPose BODY_25).
FitInput load_fit_input(const std::string& subject_dir);

}  // namespace ks
