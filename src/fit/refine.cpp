#include "fit/refine.hpp"

#include <filesystem>
#include <nlohmann/json.hpp>

#include "avatar/avatar.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "fit/fit_file.hpp"
#include "io/image_io.hpp"

namespace ks {

namespace fs = std::filesystem;

RefineFitResult refine_fit(const std::string& subject_dir, const std::string& avatar_path,
                           const RegisterOptions& options) {
  const fs::path dir(subject_dir);
  RefineFitResult out;
  out.fit_path = (dir / "fit.json").string();
  out.keypoint_fit_path = (dir / "fit_keypoints.json").string();
  if (!fs::exists(out.fit_path))
    throw Error("fit --refine-with: " + out.fit_path + " not found (run `kinesplat fit " +
                subject_dir + "` first)");
  const SubjectFit fit = load_fit(out.fit_path);
  const Avatar avatar = load_avatar(avatar_path);
  if (avatar.num_joints() != int(fit.model->parents.size()))
    throw Error("fit --refine-with: " + avatar_path + " has " +
                std::to_string(avatar.num_joints()) + " joints, the fit's body model " +
                std::to_string(fit.model->parents.size()));
  const std::string image_path = (dir / "image.png").string();
  if (!fs::exists(image_path)) throw Error("fit --refine-with: " + image_path + " not found");
  const Image image = read_image(image_path, 3);
  const std::string mask_path = (dir / "mask.png").string();
  const Image mask = fs::exists(mask_path) ? read_image(mask_path, 1) : Image();
  if (mask.width > 0 && (mask.width != image.width || mask.height != image.height))
    throw Error("fit --refine-with: " + mask_path + " is " + std::to_string(mask.width) + " x " +
                std::to_string(mask.height) + ", image.png " + std::to_string(image.width) + " x " +
                std::to_string(image.height));
  if (fit.camera.width != image.width || fit.camera.height != image.height)
    throw Error("fit --refine-with: " + out.fit_path + "'s camera is for " +
                std::to_string(fit.camera.width) + " x " + std::to_string(fit.camera.height) +
                ", image.png is " + std::to_string(image.width) + " x " +
                std::to_string(image.height));
  const float background[3] = {1.f, 1.f, 1.f};
  out.registration =
      register_pose(avatar, fit.params, fit.camera, image, mask, background, options);
  const RegisterResult& r = out.registration;

  nlohmann::json j = read_json(out.fit_path);
  if (!fs::exists(out.keypoint_fit_path)) write_json_atomic(out.keypoint_fit_path, j);
  nlohmann::json& p = j.contains("params") ? j["params"] : j["pose"];
  p["global_orient"] =
      std::vector<double>(r.params.global_orient.data(), r.params.global_orient.data() + 3);
  p["body_pose"] = std::vector<double>(r.params.body_pose.data(),
                                       r.params.body_pose.data() + r.params.body_pose.size());
  p["transl"] = std::vector<double>(r.params.transl.data(), r.params.transl.data() + 3);
  if (!j.contains("costs") || !j["costs"].is_object()) j["costs"] = nlohmann::json::object();
  j["costs"]["registration"] = {{"improved", r.improved},
                                {"cost_before", r.cost_before},
                                {"cost_after", r.cost_after},
                                {"colour_before", r.colour_before},
                                {"colour_after", r.colour_after},
                                {"mask_before", r.mask_before},
                                {"mask_after", r.mask_after},
                                {"steps", r.steps},
                                {"seconds", r.seconds}};
  j["refined_with"] = avatar_path;
  write_json_atomic(out.fit_path, j);
  return out;
}

}  // namespace ks
