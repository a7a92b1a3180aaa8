#include "fit/fit_file.hpp"

#include <cmath>
#include <filesystem>

#include "core/error.hpp"
#include "core/fileio.hpp"
#include "io/image_io.hpp"
#include "perceive/openpose.hpp"

namespace ks {

namespace fs = std::filesystem;

void save_fit(const std::string& path, const std::string& body_model, const FitResult& r,
              const nlohmann::json& extra) {
  nlohmann::json j;
  j["format"] = "kinesplat-fit";
  j["version"] = "1.0";
  j["body_model"] = body_model;
  j["betas"] =
      std::vector<double>(r.params.betas.data(), r.params.betas.data() + r.params.betas.size());
  j["params"] = r.params.to_json();
  j["camera"] = r.camera.to_json();
  j["costs"] = r.costs;
  j["facing_camera"] = r.facing_camera;
  j["seconds"] = r.seconds;
  for (auto it = extra.begin(); extra.is_object() && it != extra.end(); ++it) j[it.key()] = *it;
  write_json_atomic(path, j);
}

SubjectFit load_fit(const std::string& path) {
  const nlohmann::json j = read_json(path);
  if (!j.is_object()) throw Error(path + ": not a JSON object");
  SubjectFit f;
  try {
    if (j.contains("body_model")) f.body_model = j.at("body_model").get<std::string>();
    std::string model_path = f.body_model;
    if (model_path != "default" && fs::path(model_path).is_relative()) {
      const fs::path rel = fs::path(path).parent_path() / model_path;
      if (fs::exists(rel)) model_path = rel.string();
    }
    if (model_path == "default")
      f.model = std::shared_ptr<const BodyModel>(&default_body_model(), [](const BodyModel*) {});
    else
      f.model = std::make_shared<const BodyModel>(load_body_model(model_path));
    const char* key = j.contains("params") ? "params" : j.contains("pose") ? "pose" : nullptr;
    if (!key) throw Error("no \"params\"");
    nlohmann::json pj = j.at(key);
    if (!pj.is_object()) throw Error(std::string("\"") + key + "\" is not an object");
    if (!pj.contains("betas") && j.contains("betas")) pj["betas"] = j.at("betas");
    f.params = BodyParams::from_json(pj, *f.model);
    if (!j.contains("camera")) throw Error("no \"camera\"");
    f.camera = Camera::from_json(j.at("camera"));
    if (j.contains("costs")) f.costs = j.at("costs");
  } catch (const Error& e) {
    throw Error(path + ": " + e.what());
  } catch (const nlohmann::json::exception& e) {
    throw Error(path + ": " + e.what());
  }
  return f;
}

std::array<Eigen::Vector3d, kBody25Count> fit_keypoints(const PersonKeypoints& person) {
  // Absent ones zero, the present ones set one by one (not one assignment of a conditional value
  // a keypoint: GCC 12.2 at -O3 -march=native on an AVX-512 machine vectorised that loop into
  // wrong values, each keypoint after the first shifted by one coordinate, and the fit failed).
  std::array<Eigen::Vector3d, kBody25Count> out = absent_keypoints();
  for (int k = 0; k < kBody25Count; ++k) {
    const Keypoint2D& p = person.body[size_t(k)];
    if (p.present()) out[size_t(k)] = Eigen::Vector3d(p.x, p.y, p.conf);
  }
  return out;
}

FitInput load_fit_input(const std::string& subject_dir) {
  const fs::path dir(subject_dir);
  if (!fs::is_directory(dir)) throw Error(subject_dir + ": not a directory");
  FitInput in;
  const std::string image = (dir / "image.png").string();
  if (!fs::exists(image)) throw Error(image + ": missing (run `kinesplat perceive` first)");
  const Image img = read_image(image, 3);
  in.width = img.width;
  in.height = img.height;
  const std::string mask = (dir / "mask.png").string();
  if (fs::exists(mask)) {
    in.mask = read_image(mask, 1);
    if (in.mask.width != in.width || in.mask.height != in.height)
      throw Error(mask + ": " + std::to_string(in.mask.width) + "x" +
                  std::to_string(in.mask.height) + ", but image.png is " +
                  std::to_string(in.width) + "x" + std::to_string(in.height));
  }
  const std::string kpath = (dir / "keypoints.json").string();
  if (!fs::exists(kpath)) throw Error(kpath + ": missing (run `kinesplat perceive` first)");
  // kinesplat's own keypoint files put pixel centres at integer + 0.5.
  KeypointReadOptions ko;
  ko.pixel_centre = 0.5;
  const KeypointFile kf = read_keypoints(kpath, ko);
  in.keypoints = fit_keypoints(kf.person);
  // The focal length perceive found in the photo's metadata (older subjects have none).
  const std::string ppath = (dir / "perceive.json").string();
  if (fs::exists(ppath)) {
    const nlohmann::json pj = read_json(ppath);
    const auto img = pj.find("image");
    if (img != pj.end() && img->is_object() && img->contains("focal_px")) {
      const auto& f = (*img)["focal_px"];
      if (!f.is_number() || !(f.get<double>() > 0) || !std::isfinite(f.get<double>()))
        throw Error(ppath + ": image.focal_px must be a positive number");
      in.metadata_focal = f.get<double>();
    }
  }
  return in;
}

}  // namespace ks
