#pragma once
// `track`'s temporal terms over a sequence's frames (track/temporal.hpp solves with them): each
// frame's posed points (the body joints and the BODY_25 points) in the fixed camera's frame,
// followed across neighbouring frames. A difference over two frames is the velocity term, over
// three the acceleration term; both in units of their prior's standard deviation:
//  - acceleration: the points move as a white-noise-acceleration process of density sigma_a^2
//    (m^2 s^-3); for frames at t0 < t1 < t2 (steps h0, h1) the change of velocity
//    (p2 - p1) / h1 - (p1 - p0) / h0 has standard deviation sigma_a sqrt((h0 + h1) / 3), so the
//    residual's weight follows the frames' spacing (a sparsely sampled video is smoothed less);
//  - velocity: a random walk of density sigma_v^2 (m^2 s^-1); p1 - p0 has deviation
//    sigma_v sqrt(h0).
// One residual block per point (3 residuals), so that a robust loss lets a point's genuine peaks
// through (a foot in a walk accelerates at 30 m/s^2, the pelvis at 2) while it smooths jitter.
// The derivatives come from each frame's own Evaluator (derivatives with respect to that frame's
// packed parameters), combined linearly; tests/track/temporal_terms_test.cpp checks them against
// finite differences.
#include <ceres/ceres.h>

#include <vector>

#include "fit/evaluator.hpp"

namespace ks::track {

// The points a temporal term follows: the first `joints` posed joints, then the 25 BODY_25 points.
int temporal_point_count(int joints);

// Point q (a joint below `joints`, else BODY_25 point q - joints) of one frame in the camera's
// frame (to_camera with the frame's camera translation at layout offset `cam`), with derivatives
// with respect to the frame's parameters.
fit::Vec3J camera_point(const fit::Evaluator& ev, const double* x, int cam, int joints, int q);

// r = scale * sum_i coeff_i * p_i(q) for one point q, one parameter block per frame.
class TemporalResidual : public ceres::CostFunction {
 public:
  TemporalResidual(std::vector<const fit::Evaluator*> frames, std::vector<double> coeff,
                   double scale, int num_params, int cam, int joints, int point);
  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override;

 private:
  std::vector<const fit::Evaluator*> ev_;
  std::vector<double> c_;
  double s_;
  int P_, cam_, joints_, q_;
};

// The acceleration term of point q in frames at times t0 < t1 < t2, deviation density sigma_a.
TemporalResidual* acceleration_residual(const fit::Evaluator* e0, const fit::Evaluator* e1,
                                        const fit::Evaluator* e2, double t0, double t1, double t2,
                                        double sigma_a, int num_params, int cam, int joints, int q);

// The velocity term of point q in frames at times t0 < t1, deviation density sigma_v.
TemporalResidual* velocity_residual(const fit::Evaluator* e0, const fit::Evaluator* e1, double t0,
                                    double t1, double sigma_v, int num_params, int cam, int joints,
                                    int q);

// Prepares every frame's Evaluator before each of Ceres' evaluations (one callback per problem).
class SequenceEvaluator : public ceres::EvaluationCallback {
 public:
  explicit SequenceEvaluator(std::vector<fit::Evaluator*> frames) : ev_(std::move(frames)) {}
  void PrepareForEvaluation(bool jacobians, bool new_point) override;

 private:
  std::vector<fit::Evaluator*> ev_;
};

}  // namespace ks::track
