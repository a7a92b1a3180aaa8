#pragma once
// `fit`: body-model parameters and camera from 2D keypoints and a person mask, SMPLify-style
// robust least squares (Ceres), in stages: camera translation and global orientation from the
// torso; then the body pose; then the shape with the silhouette. Terms:
//  - keypoints: reprojection of the BODY_25 points (body/keypoints.hpp), weighted by confidence,
//    robust (Cauchy), in units of 1% of the person's height in pixels;
//  - silhouette, both ways: body vertices outside the mask (the mask's outside distance
//    transform at their projection) and the mask's outline away from the body's (each outline
//    sample against its nearest body-outline vertex, correspondences renewed each round), the
//    second one-sided beyond a clothing allowance;
//  - pose prior without licensed weights: soft anatomical joint-angle limits (knees and elbows
//    bend one way), closeness to a natural stance (strongest on the twists keypoints cannot
//    see); shape prior (betas towards zero); arms kept out of the torso.
// Camera: pinhole, principal point at the image centre, focal from the options; a level camera
// on the body's +Z side (the body's global orientation takes any pitch or roll of the photo).
// World: metres, Y up, the body facing +Z in its rest pose; the body's transl is zero.
#include <Eigen/Core>
#include <array>
#include <map>
#include <string>
#include <vector>

#include "body/body_model.hpp"
#include "body/keypoints.hpp"
#include "core/camera.hpp"
#include "core/image.hpp"

namespace ks {

// One stage of the fit's schedule: a Levenberg-Marquardt solve over the parameter blocks it frees,
// with the terms it switches on. Keypoints, the upright term and (with free_pose) the joint limits
// and the arms-out-of-the-torso term are on in every stage that frees what they act on.
struct FitStage {
  enum class Kind {
    kSolve,       // one solve (`rounds` of them with the silhouette)
    kDepthFlips,  // each limb (and pair) mirrored in depth, solved with this stage's terms, kept
                  // where the cost falls below the previous stage's
  };
  std::string name;
  Kind kind = Kind::kSolve;
  bool free_orient = true, free_pose = false, free_betas = false, free_cam = true;
  bool torso_only = false;  // keypoints of the torso only (neck, shoulders, hips); no upright term
  double prior_scale = 0;   // the stance prior's weight in units of FitOptions::w_pose_prior
  bool silhouette = false;  // the silhouette terms, where there is a mask
  int rounds = 1;           // with the silhouette: solves, the correspondences renewed before each
};

// The schedule: `per_start` runs from each standing start (facing the camera and turned away), the
// lower final cost decides (an early stage's strong prior can favour the wrong one); `refine` then
// runs from the winner. The last stage's per-term costs are the fit's `costs`.
struct FitSchedule {
  std::vector<FitStage> per_start, refine;
};

// Torso (camera and orientation from the torso's keypoints); pose with the stance prior at 10x, 3x
// and 1x; depth flips; then pose + shape + silhouette (3 correspondence rounds). docs/fit.md.
FitSchedule default_fit_schedule();

struct FitOptions {
  // Camera: focal length in pixels; <= 0: from the field of view across the image's long side.
  double focal = 0;
  double fov_degrees = 40.0;
  int num_betas = 10;  // shape coefficients fitted (at most the model's)
  // The shape the fit starts from (its first num_betas coefficients; the rest zero); empty: the
  // mean shape (zeros). With free_betas false in every stage the fit keeps it (`track`'s second
  // pass: one shape for all frames).
  Eigen::VectorXd initial_betas;
  // What the keypoints mark (body/keypoints.hpp): COCO's places (every detector; perceive's
  // output) or the body model's joints (the synth's true keypoints).
  KeypointConvention keypoints = KeypointConvention::kCoco;
  int vertex_stride = 6;  // every n-th template vertex is a silhouette sample
  // Term weights (residuals in % of the person's pixel height, or radians for the pose prior).
  double w_keypoints = 1.0;
  double keypoint_robust = 3.0;  // Cauchy scale, % of height
  double w_face = 0.3;           // nose, eyes, ears (relative)
  double w_feet = 0.5;           // toes and heels (relative)
  // Closeness to the natural stance (standing, arms lowered by `stance_arm_down_degrees` from the
  // T-pose), per joint a Gaussian on the bone's swing and twist with everyday deviations; each
  // stage scales it by its prior_scale.
  double w_pose_prior = 4.0;
  double stance_arm_down_degrees = 70.0;
  double w_limits = 20.0;  // joint-angle limits
  // The body upright (its pelvis' up axis near the world's): how far it may lean, and the weight.
  double upright_sigma_degrees = 20.0;
  double w_upright = 4.0;
  // Both feet on the ground: the ankles at one height (robust: a lifted foot stays allowed), the
  // cue that tells which leg is nearer the camera.
  double w_ground = 0.05;
  double ground_robust_cm = 4.0;
  double w_shape = 0.3;               // betas
  double w_arm_torso = 20.0;          // arms out of the torso
  double w_sil_inside = 4.0;          // body outside the mask
  double w_sil_cover = 0.3;           // mask outline away from the body's
  double clothing_allowance = 0.015;  // metres: the mask may stand this far off the body
  double cover_robust = 1.0;          // Cauchy scale of the cover term, % of height
  int max_iterations = 60;            // per solve
  bool use_silhouette = true;         // (needs a mask)
  bool progress = false;
  FitSchedule schedule = default_fit_schedule();
};

inline std::array<Eigen::Vector3d, kBody25Count> absent_keypoints() {
  std::array<Eigen::Vector3d, kBody25Count> k;
  k.fill(Eigen::Vector3d::Zero());
  return k;
}

struct FitInput {
  int width = 0, height = 0;
  // BODY_25 keypoints (x, y, confidence) in pixels (pixel centres at integer + 0.5); confidence
  // 0 = absent.
  std::array<Eigen::Vector3d, kBody25Count> keypoints = absent_keypoints();
  Image mask;  // 1 channel in [0, 1] (>= 0.5 = person), width x height; empty = no silhouette
  // The focal length (pixels) the photo's metadata gives (perceive.json's image.focal_px, from
  // EXIF); 0 when it gives none. Used where FitOptions::focal is not set.
  double metadata_focal = 0;
};

struct FitResult {
  BodyParams params;  // betas, global_orient, body_pose (transl zero)
  Camera camera;
  std::map<std::string, double> costs;  // each term's final cost (Ceres' 1/2 sum of squares)
  bool facing_camera = true;            // the fitted body's front faces the camera
  double seconds = 0;
};

// The focal length the fit uses for `input`: options.focal, else the input's metadata focal, else
// from the field of view; `source` (optional): "option", "metadata" or "field of view".
double fit_focal(const FitOptions& options, const FitInput& input, std::string* source = nullptr);

// Throws ks::Error when too few keypoints are given (the torso needs the neck or both
// shoulders and both hips), or the mask's size differs from the image's.
FitResult fit_body(const BodyModel& model, const FitInput& input, const FitOptions& options = {});

// The focal length (pixels) the fit uses for an image: options.focal, or from the field of view
// across the image's long side.
double fit_focal(const FitOptions& options, int width, int height);

// The camera the fit uses for an image (focal from fit_focal, principal point at the centre,
// rotation fit_body.hpp's camera_rotation), with translation t.
Camera fit_camera(const FitOptions& options, int width, int height, const Eigen::Vector3d& t);

}  // namespace ks
