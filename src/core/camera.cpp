#include "core/camera.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "core/fileio.hpp"

namespace ks {

Camera Camera::look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target,
                       const Eigen::Vector3d& up, int width, int height, double fx, double fy,
                       double cx, double cy) {
  Eigen::Vector3d z = (target - eye).normalized();  // forward
  Eigen::Vector3d x = z.cross(up).normalized();     // right (image x)
  if (!std::isfinite(x.norm()) || x.norm() < 0.5) x = Eigen::Vector3d::UnitX();
  Eigen::Vector3d y = z.cross(x);  // down (image y)
  Camera c;
  c.width = width;
  c.height = height;
  c.fx = fx;
  c.fy = fy;
  c.cx = cx;
  c.cy = cy;
  c.R.row(0) = x.transpose();
  c.R.row(1) = y.transpose();
  c.R.row(2) = z.transpose();
  c.t = -c.R * eye;
  return c;
}

Camera Camera::look_at_fov(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, int width,
                           int height, double vfov_degrees) {
  const double f = 0.5 * height / std::tan(0.5 * vfov_degrees * M_PI / 180.0);
  return look_at(eye, target, Eigen::Vector3d::UnitY(), width, height, f, f, 0.5 * width,
                 0.5 * height);
}

Camera Camera::from_json(const nlohmann::json& j) {
  if (!j.is_object()) throw Error("camera: expected a JSON object");
  for (const char* key : {"width", "height", "fx", "fy", "cx", "cy", "R", "t"})
    if (!j.contains(key)) throw Error(std::string("camera: missing key \"") + key + "\"");
  Camera c;
  try {
    for (const char* key : {"width", "height"}) {
      const auto& v = j.at(key);
      if (!v.is_number_integer() || v.get<int64_t>() <= 0 || v.get<int64_t>() > (1 << 20))
        throw Error(std::string("camera: \"") + key +
                    "\" must be a whole number of pixels in [1, " + std::to_string(1 << 20) + "]");
    }
    c.width = int(j.at("width").get<int64_t>());
    c.height = int(j.at("height").get<int64_t>());
    c.fx = j.at("fx").get<double>();
    c.fy = j.at("fy").get<double>();
    c.cx = j.at("cx").get<double>();
    c.cy = j.at("cy").get<double>();
    const auto& R = j.at("R");
    if (!R.is_array() || R.size() != 3) throw Error("camera: \"R\" must be a 3x3 array");
    for (int r = 0; r < 3; ++r) {
      if (!R[r].is_array() || R[r].size() != 3) throw Error("camera: \"R\" must be a 3x3 array");
      for (int k = 0; k < 3; ++k) c.R(r, k) = R[r][k].get<double>();
    }
    const auto& t = j.at("t");
    if (!t.is_array() || t.size() != 3) throw Error("camera: \"t\" must be an array of 3 numbers");
    for (int k = 0; k < 3; ++k) c.t[k] = t[k].get<double>();
  } catch (const nlohmann::json::exception& e) {
    throw Error(std::string("camera: wrong value type: ") + e.what());
  }
  if (c.width <= 0 || c.height <= 0) throw Error("camera: width and height must be positive");
  if (!std::isfinite(c.fx) || !std::isfinite(c.fy) || !std::isfinite(c.cx) ||
      !std::isfinite(c.cy) || !c.R.allFinite() || !c.t.allFinite())
    throw Error("camera: fx, fy, cx, cy, R and t must be finite numbers");
  if (!(c.fx > 0) || !(c.fy > 0)) throw Error("camera: fx and fy must be positive");
  const double orth = (c.R * c.R.transpose() - Eigen::Matrix3d::Identity()).norm();
  if (!(orth < 1e-3) || c.R.determinant() < 0)
    throw Error("camera: \"R\" is not a rotation matrix (orthonormal, determinant +1)");
  return c;
}

nlohmann::json Camera::to_json() const {
  nlohmann::json j;
  j["width"] = width;
  j["height"] = height;
  j["fx"] = fx;
  j["fy"] = fy;
  j["cx"] = cx;
  j["cy"] = cy;
  j["R"] = {{R(0, 0), R(0, 1), R(0, 2)}, {R(1, 0), R(1, 1), R(1, 2)}, {R(2, 0), R(2, 1), R(2, 2)}};
  j["t"] = {t[0], t[1], t[2]};
  return j;
}

Camera Camera::load(const std::string& path) {
  const nlohmann::json j = read_json(path);
  try {
    return from_json(j);
  } catch (const Error& e) {
    throw Error(path + ": " + e.what());
  }
}

void Camera::save(const std::string& path) const {
  write_text_atomic(path, to_json().dump(2));
}

Camera scale_camera(const Camera& cam, int width, int height) {
  Camera c = cam;
  const double sx = double(width) / cam.width, sy = double(height) / cam.height;
  c.width = width;
  c.height = height;
  c.fx *= sx;
  c.cx *= sx;
  c.fy *= sy;
  c.cy *= sy;
  return c;
}

}  // namespace ks
