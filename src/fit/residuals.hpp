#pragma once
// The fit's objective, one residual type per term (fit.hpp lists what each measures). Each term
// reads the body through the shared Evaluator (fit/evaluator.hpp) and the packed parameter vector
// (fit_body.hpp's Layout); its residuals and their derivatives come from one templated
// computation in Jets (`JetResidual<N>`, N residuals) or, for the linear shape prior, in closed
// form. tests/fit/residuals_test.cpp checks each one's Jacobian against finite differences.
#include <ceres/ceres.h>

#include <Eigen/Core>
#include <array>

#include "fit/evaluator.hpp"
#include "fit/pose_prior.hpp"
#include "fit/silhouette.hpp"

namespace ks::fit {

// A residual block of N residuals over the one parameter vector, computed in Jets by `compute`.
template <int N>
class JetResidual : public ceres::CostFunction {
 public:
  explicit JetResidual(int num_params) {
    set_num_residuals(N);
    mutable_parameter_block_sizes()->push_back(num_params);
  }
  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override {
    std::array<Jet, N> r;
    if (!compute(params[0], r)) return false;
    const int P = parameter_block_sizes()[0];
    for (int i = 0; i < N; ++i) {
      residuals[i] = r[size_t(i)].a;
      if (jacobians && jacobians[0])
        for (int c = 0; c < P; ++c) jacobians[0][size_t(i) * P + c] = r[size_t(i)].v[c];
    }
    return true;
  }
  // The residuals at parameters x; false where they are not defined (Ceres then steps back).
  virtual bool compute(const double* x, std::array<Jet, N>& r) const = 0;
};

// Pixel error of BODY_25 point k against its detection, in units of `unit` pixels.
class KeypointResidual : public JetResidual<2> {
 public:
  KeypointResidual(const Evaluator& ev, const Projector& pr, int k, Eigen::Vector2d target,
                   double unit, int P)
      : JetResidual(P), ev_(ev), pr_(pr), k_(k), target_(target), unit_(unit) {}
  bool compute(const double* x, std::array<Jet, 2>& r) const override;

 private:
  const Evaluator& ev_;
  const Projector& pr_;
  int k_;
  Eigen::Vector2d target_;
  double unit_;
};

// A body vertex (slot m of the vertex subset) outside the mask: the outside distance at its
// projection, in units of `unit` pixels.
class InsideResidual : public JetResidual<1> {
 public:
  InsideResidual(const Evaluator& ev, const Projector& pr, const DistanceField& df, int m,
                 double unit, int P)
      : JetResidual(P), ev_(ev), pr_(pr), df_(df), m_(m), unit_(unit) {}
  bool compute(const double* x, std::array<Jet, 1>& r) const override;

 private:
  const Evaluator& ev_;
  const Projector& pr_;
  const DistanceField& df_;
  int m_;
  double unit_;
};

// A mask outline sample q against its body-outline vertex m, beyond `allowance` pixels.
class CoverResidual : public JetResidual<2> {
 public:
  CoverResidual(const Evaluator& ev, const Projector& pr, int m, Eigen::Vector2d q,
                double allowance, double unit, int P)
      : JetResidual(P), ev_(ev), pr_(pr), m_(m), q_(q), allowance_(allowance), unit_(unit) {}
  bool compute(const double* x, std::array<Jet, 2>& r) const override;

 private:
  const Evaluator& ev_;
  const Projector& pr_;
  int m_;
  Eigen::Vector2d q_;
  double allowance_, unit_;
};

// Closeness of one body-pose joint (its axis-angle at `offset`) to the natural stance: the swing
// of the bone (3 residuals) and the twist about it (1), each in its prior's deviations.
class PoseResidual : public JetResidual<4> {
 public:
  PoseResidual(const JointPrior& jp, int offset, int P) : JetResidual(P), jp_(jp), off_(offset) {}
  bool compute(const double* x, std::array<Jet, 4>& r) const override;

 private:
  JointPrior jp_;
  int off_;
};

// Soft joint-angle limits of one body-pose joint: each axis-angle component beyond its range.
class LimitResidual : public JetResidual<3> {
 public:
  LimitResidual(const JointPrior& jp, int offset, int P) : JetResidual(P), jp_(jp), off_(offset) {}
  bool compute(const double* x, std::array<Jet, 3>& r) const override;

 private:
  JointPrior jp_;
  int off_;
};

// The body stands upright: the global orientation's (at `offset`) up axis, its rotation of +Y,
// near the world's +Y, in units of `sigma` radians of tilt.
class UprightResidual : public JetResidual<2> {
 public:
  UprightResidual(int offset, double sigma, double w, int P)
      : JetResidual(P), off_(offset), s_(std::sqrt(w) / sigma) {}
  bool compute(const double* x, std::array<Jet, 2>& r) const override;

 private:
  int off_;
  double s_;
};

// Both feet on one ground: joints a and b (the ankles) at the same height along the world's up
// axis, in centimetres (used with a robust loss, so a lifted foot is allowed).
class GroundResidual : public JetResidual<1> {
 public:
  GroundResidual(const Evaluator& ev, int a, int b, int P)
      : JetResidual(P), ev_(ev), a_(a), b_(b) {}
  bool compute(const double* x, std::array<Jet, 1>& r) const override;

 private:
  const Evaluator& ev_;
  int a_, b_;
};

// An arm joint inside the torso (a capsule of `radius` metres from the pelvis to the neck), in
// centimetres.
class ArmTorsoResidual : public JetResidual<1> {
 public:
  ArmTorsoResidual(const Evaluator& ev, int joint, double radius, double w, int P)
      : JetResidual(P), ev_(ev), joint_(joint), radius_(radius), s_(std::sqrt(w)) {}
  bool compute(const double* x, std::array<Jet, 1>& r) const override;

 private:
  const Evaluator& ev_;
  int joint_;
  double radius_, s_;
};

// Shape prior: the n betas at `offset` towards zero, sqrt(w) each. Linear, so its Jacobian is
// written out (no Jets).
class ShapeResidual : public ceres::CostFunction {
 public:
  ShapeResidual(int offset, int n, double w, int P);
  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override;

 private:
  int off_, n_;
  double s_;
};

}  // namespace ks::fit
