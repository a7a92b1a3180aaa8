#pragma once
// What `track` writes: TRACK/track.json (format "kinesplat-track" 1.0: the shared betas, the
// focal, per frame the fit's params and camera in fit.json's fields) and TRACK/motion.npz (the
// AMASS layout motion/amass.hpp reads and writes: the camera fixed, the body moving in the world).
#include <nlohmann/json.hpp>
#include <string>

#include "motion/motion.hpp"
#include "track/track.hpp"

namespace ks {

nlohmann::json track_json(const TrackResult& track);

// The world motion of a fixed camera: frame f's body translation = camera_rotation()^T (b_f - b_0)
// with b_f = t_f + R transl_f where the body sits in the camera (the fit's camera is
// world-to-camera X_c = R X + t; transl is zero from the keypoint fit, set by registration); poses
// = global_orient + body_pose; fps = track.fps.
Motion track_motion(const TrackResult& track);

}  // namespace ks
