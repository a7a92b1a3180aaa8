#pragma once
// A synthetic clothed person with exact ground truth: a body model (the default or a user's SMPL
// .npz), subdivided, with clothing and hair as displacements along the rest-pose normals and
// per-vertex albedo (synth/appearance.hpp), a skirt mesh where the outfit has one
// (synth/skirt.hpp), BODY_25 keypoint sources (synth/keypoints.hpp). The person poses with the
// body's skin weights: posed = sum_j w_j T_j (rest + displacement + pose correctives), T_j from
// body_forward. Everything is deterministic in the seed (synth/rng.hpp).
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <array>
#include <memory>
#include <string>
#include <vector>

#include "body/body_model.hpp"
#include "body/keypoints.hpp"
#include "body/lbs.hpp"
#include "core/camera.hpp"
#include "meshrender/meshrender.hpp"
#include "synth/appearance.hpp"

namespace ks {

struct SynthOptions {
  int subdivision_levels = 2;  // Loop subdivision steps of the body mesh (colour detail)
};

struct SynthPerson {
  std::shared_ptr<const BodyModel> model;
  std::string body_model = "default";  // "default" or the model's path
  uint64_t seed = 0;
  Eigen::VectorXd betas;
  SynthAppearance appearance;
  // The clothed surface in the rest pose (shaped by betas, displaced), N x 3.
  Eigen::MatrixXd rest;
  Eigen::MatrixXi faces;
  Eigen::MatrixXd colors;   // N x 3 albedo
  std::vector<int> labels;  // N body-part labels (ks::Part)
  // Body mesh -> person mesh stencil (carries the model's pose correctives); its rows are the
  // first vertices of the person (a skirt's vertices follow them).
  Eigen::SparseMatrix<double, Eigen::RowMajor> stencil;
  // Skin weights, top 4 joints per vertex (weights sum to 1).
  SkinJoints skin_joints;    // N x 4
  SkinWeights skin_weights;  // N x 4
  // BODY_25 sources: a joint of the skeleton, a vertex of the surface, or (MidHip) the mean of
  // two joints. Exactly one of joint/vertex is >= 0 per keypoint (MidHip: joint and joint2).
  std::array<int, kBody25Count> kp_joint{}, kp_joint2{}, kp_vertex{};
  std::array<double, kBody25Count> kp_depth_tolerance{};  // metres, for the visibility test
};

struct PosedPerson {
  Eigen::MatrixXd vertices;  // N x 3 world
  Eigen::MatrixXd joints;    // J x 3 world
};

// Builds a person on `model` (`body_model` is the name written to datasets: "default" or a
// path). Throws ks::Error if the model does not have SMPL's first 22 joints.
// The bare body as a person mesh: the shaped rest body (betas), Loop-subdivided `levels` times,
// part labels and top-4 skin weights carried by the stencil, grey. The synth dresses it; the
// lift generator colours it from a photo.
SynthPerson body_mesh_person(std::shared_ptr<const BodyModel> model, const std::string& body_model,
                             const Eigen::VectorXd& betas, int levels);
SynthPerson make_synth_person(std::shared_ptr<const BodyModel> model, const std::string& body_model,
                              uint64_t seed, const SynthOptions& options = {});
// Poses the person (pose.betas is ignored: the person's betas are used).
PosedPerson pose_synth_person(const SynthPerson& person, const BodyParams& pose);
// The full body parameters of a pose for this person (its betas, body_pose fitted to the model).
BodyParams synth_params(const SynthPerson& person, const BodyParams& pose);

// Renders the posed person (unlit albedo by default). Outputs rgb, mask and depth.
MeshRenderOutput render_synth(const SynthPerson& person, const PosedPerson& posed,
                              const Camera& camera, int supersample = 2,
                              const Eigen::Vector3d& background = {1.0, 1.0, 1.0},
                              bool lighting = false);

// A portrait camera seeing every vertex of `poses` from azimuth `azimuth_deg` about world Y
// (0: in front of the body, on +Z; 90: on the body's left, +X; 180: behind), level with and
// looking horizontally at the middle of their bounding box, distance chosen so that they span
// `fill` of the image height (or 94% of its width, whichever is tighter). Vertical FOV fixed.
Camera synth_camera(const std::vector<const Eigen::MatrixXd*>& poses, double azimuth_deg, int width,
                    int height, double vfov_degrees = 35.0, double fill = 0.87);

}  // namespace ks
