#include "track/track_file.hpp"

#include <Eigen/Core>

#include "core/error.hpp"
#include "core/rotation.hpp"
#include "fit/fit_body.hpp"
#include "motion/amass.hpp"

namespace ks {

nlohmann::json track_json(const TrackResult& t) {
  nlohmann::json j;
  j["format"] = "kinesplat-track";
  j["version"] = "1.0";
  j["body_model"] = t.body_model;
  j["betas"] = std::vector<double>(t.betas.data(), t.betas.data() + t.betas.size());
  j["focal"] = t.focal;
  j["focal_from"] = t.focal_from;
  j["width"] = t.width;
  j["height"] = t.height;
  j["fps"] = t.fps;
  j["input_fps"] = t.input_fps;
  j["input"] = t.video ? "video" : "images";
  j["camera_fixed"] = true;
  nlohmann::json frames = nlohmann::json::array();
  for (const TrackFrame& f : t.frames) {
    BodyParams p = f.fit.params;
    p.betas = t.betas;
    nlohmann::json fj;
    fj["index"] = f.index;
    fj["time"] = f.time_s;
    fj["source"] = f.source;
    fj["subject"] = f.subject;
    fj["params"] = p.to_json();
    fj["camera"] = f.fit.camera.to_json();
    const auto c = f.fit.costs.find("total");
    fj["confidence"] = {{"cost", c == f.fit.costs.end() ? 0.0 : c->second},
                        {"what", "the fit's final total cost (lower is better)"}};
    fj["costs"] = f.fit.costs;
    fj["facing_camera"] = f.fit.facing_camera;
    fj["keypoints_used"] = f.keypoints_used;
    fj["swapped"] = f.swapped;
    fj["restarted"] = f.restarted;
    if (f.registered) {
      const RegisterResult& g = f.registration;
      BodyParams kp = f.keypoint_params;
      kp.betas = t.betas;
      fj["registration"] = {{"improved", g.improved},     {"cost_before", g.cost_before},
                            {"cost_after", g.cost_after}, {"mask_before", g.mask_before},
                            {"mask_after", g.mask_after}, {"steps", g.steps},
                            {"seconds", g.seconds},       {"keypoint_params", kp.to_json()}};
    }
    const auto cs = f.shared.costs.find("total");
    if (t.shared_pass)
      fj["shared"] = {{"params", f.shared.params.to_json()},
                      {"camera", f.shared.camera.to_json()},
                      {"cost", cs == f.shared.costs.end() ? 0.0 : cs->second}};
    const auto ci = f.independent.costs.find("total");
    fj["independent"] = {{"betas", std::vector<double>(f.independent.params.betas.data(),
                                                       f.independent.params.betas.data() +
                                                           f.independent.params.betas.size())},
                         {"params", f.independent.params.to_json()},
                         {"camera", f.independent.camera.to_json()},
                         {"cost", ci == f.independent.costs.end() ? 0.0 : ci->second}};
    frames.push_back(fj);
  }
  j["frames"] = frames;
  j["skipped"] = t.skipped;
  j["sequence"] = t.sequence;
  j["shared_pass"] = t.shared_pass;
  j["temporal"] = {
      {"applied", t.temporal.applied},       {"cost_before", t.temporal.cost_before},
      {"cost_after", t.temporal.cost_after}, {"temporal_cost", t.temporal.temporal_cost},
      {"swapped", t.temporal.swapped},       {"restarted", t.temporal.restarted},
      {"solves", t.temporal.solves},         {"seconds", t.temporal.seconds}};
  j["perceive_seconds"] = t.perceive_seconds;
  j["fit_seconds"] = t.fit_seconds;
  return j;
}

Motion track_motion(const TrackResult& t) {
  if (t.frames.empty()) throw Error("track: no frames to make a motion of");
  Motion m;
  m.name = "track";
  m.fps = t.fps;
  const Eigen::Matrix3d R = fit::camera_rotation();
  // The body's own translation (zero from the keypoint fit, set by registration) moves it in the
  // camera as the camera's translation R transl would: both go into the world translation.
  const auto body_in_camera = [&](const TrackFrame& f) {
    return Eigen::Vector3d(f.fit.camera.t + R * f.fit.params.transl);
  };
  const Eigen::Vector3d t0 = body_in_camera(t.frames.front());
  for (const TrackFrame& f : t.frames) {
    BodyParams b;
    b.global_orient = f.fit.params.global_orient;
    b.body_pose = f.fit.params.body_pose;
    b.transl = R.transpose() * (body_in_camera(f) - t0);
    m.frames.push_back(std::move(b));
  }
  return m;
}

}  // namespace ks
