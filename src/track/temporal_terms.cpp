#include "track/temporal_terms.hpp"

#include <cmath>

#include "body/keypoints.hpp"
#include "core/error.hpp"
#include "fit/fit_body.hpp"

namespace ks::track {

int temporal_point_count(int joints) {
  return joints + kBody25Count;
}

fit::Vec3J camera_point(const fit::Evaluator& ev, const double* x, int cam, int joints, int q) {
  using fit::Jet;
  const fit::Vec3J t(Jet(x[cam], cam), Jet(x[cam + 1], cam + 1), Jet(x[cam + 2], cam + 2));
  return fit::to_camera(q < joints ? ev.joint(q) : ev.keypoint(q - joints), t);
}

TemporalResidual::TemporalResidual(std::vector<const fit::Evaluator*> frames,
                                   std::vector<double> coeff, double scale, int num_params, int cam,
                                   int joints, int point)
    : ev_(std::move(frames)),
      c_(std::move(coeff)),
      s_(scale),
      P_(num_params),
      cam_(cam),
      joints_(joints),
      q_(point) {
  if (ev_.size() != c_.size() || ev_.empty())
    throw Error("track: a temporal term needs one coefficient per frame");
  if (point < 0 || point >= temporal_point_count(joints))
    throw Error("track: a temporal term's point is out of range");
  set_num_residuals(3);
  for (size_t i = 0; i < ev_.size(); ++i) mutable_parameter_block_sizes()->push_back(num_params);
}

bool TemporalResidual::Evaluate(double const* const* params, double* residuals,
                                double** jacobians) const {
  std::fill(residuals, residuals + 3, 0.0);
  for (size_t i = 0; i < ev_.size(); ++i) {
    const fit::Vec3J p = camera_point(*ev_[i], params[i], cam_, joints_, q_);
    const double w = s_ * c_[i];
    double* J = jacobians ? jacobians[i] : nullptr;
    for (int k = 0; k < 3; ++k) {
      if (!(p(k).a == p(k).a)) return false;
      residuals[k] += w * p(k).a;
      if (J)
        for (int c = 0; c < P_; ++c) J[size_t(k) * size_t(P_) + size_t(c)] = w * p(k).v[c];
    }
  }
  return true;
}

TemporalResidual* acceleration_residual(const fit::Evaluator* e0, const fit::Evaluator* e1,
                                        const fit::Evaluator* e2, double t0, double t1, double t2,
                                        double sigma_a, int num_params, int cam, int joints,
                                        int q) {
  const double h0 = t1 - t0, h1 = t2 - t1;
  if (!(h0 > 0 && h1 > 0 && sigma_a > 0))
    throw Error("track: the acceleration term needs increasing times and a positive deviation");
  const double scale = 1.0 / (sigma_a * std::sqrt((h0 + h1) / 3.0));
  return new TemporalResidual({e0, e1, e2}, {1.0 / h0, -(1.0 / h0 + 1.0 / h1), 1.0 / h1}, scale,
                              num_params, cam, joints, q);
}

TemporalResidual* velocity_residual(const fit::Evaluator* e0, const fit::Evaluator* e1, double t0,
                                    double t1, double sigma_v, int num_params, int cam, int joints,
                                    int q) {
  const double h = t1 - t0;
  if (!(h > 0 && sigma_v > 0))
    throw Error("track: the velocity term needs increasing times and a positive deviation");
  return new TemporalResidual({e0, e1}, {-1.0, 1.0}, 1.0 / (sigma_v * std::sqrt(h)), num_params,
                              cam, joints, q);
}

void SequenceEvaluator::PrepareForEvaluation(bool jacobians, bool new_point) {
  const int n = int(ev_.size());
#pragma omp parallel for schedule(dynamic)
  for (int i = 0; i < n; ++i) ev_[size_t(i)]->PrepareForEvaluation(jacobians, new_point);
}

}  // namespace ks::track
