#pragma once
// What every residual of the fit reads: the body's forward model evaluated once per Ceres
// evaluation (values, or values with derivatives as Jets), and the pinhole projection of a world
// point through the fit's camera. The terms themselves are in fit/residuals.hpp.
#include <ceres/ceres.h>

#include <Eigen/Core>
#include <vector>

#include "fit/fit_body.hpp"

namespace ks::fit {

// Derivatives with respect to every entry of the packed parameter vector (fit_body.hpp's Layout).
using Jet = ceres::Jet<double, kMaxParams>;
using Vec3J = Eigen::Matrix<Jet, 3, 1>;

// Shares the body's forward model between all residual blocks: Ceres calls it before each
// evaluation with the parameters already in `x`.
class Evaluator : public ceres::EvaluationCallback {
 public:
  // all_vertices: the whole vertex subset (silhouette terms), else only the keypoints' vertices.
  Evaluator(const BodyData& d, const double* x, bool all_vertices);
  void PrepareForEvaluation(bool jacobians, bool new_point) override;
  const Vec3J& joint(int j) const { return joints_[size_t(j)]; }
  const Vec3J& vertex(int m) const { return vertices_[size_t(m)]; }
  // BODY_25 point k.
  const Vec3J& keypoint(int k) const { return keypoints_[size_t(k)]; }

 private:
  const std::vector<int>* only() const { return only_.empty() ? nullptr : &only_; }
  const BodyData& d_;
  const double* x_;
  std::vector<int> only_;
  std::vector<Vec3J> joints_, vertices_, keypoints_;
  bool have_jacobians_ = false;
};

// Pixel coordinates of a world point through the fit's camera: focal f, principal point (cx, cy),
// the fixed rotation (fit_body.hpp's to_camera) and the translation held in the parameters at
// offset `cam`.
struct Projector {
  double f = 1, cx = 0, cy = 0;
  int cam = 0;  // offset of the camera translation in the parameters
  void project(const Vec3J& X, const double* x, Jet* u, Jet* v) const;
};

}  // namespace ks::fit
