#include "fit/evaluator.hpp"

namespace ks::fit {

namespace {

void copy_values(const std::vector<Eigen::Vector3d>& in, std::vector<Vec3J>& out) {
  out.resize(in.size());
  for (size_t i = 0; i < in.size(); ++i)
    for (int k = 0; k < 3; ++k) out[i](k) = Jet(in[i](k));
}

}  // namespace

Evaluator::Evaluator(const BodyData& d, const double* x, bool all_vertices) : d_(d), x_(x) {
  if (!all_vertices)
    for (int k = 0; k < kBody25Count; ++k)
      if (d.kp[size_t(k)].vertex >= 0) only_.push_back(d.kp_slot[size_t(k)]);
}

void Evaluator::PrepareForEvaluation(bool jacobians, bool new_point) {
  if (!new_point && (have_jacobians_ || !jacobians)) return;
  const int P = d_.layout.size;
  if (jacobians) {
    std::vector<Jet> xj(static_cast<size_t>(P));
    for (int i = 0; i < P; ++i) xj[size_t(i)] = Jet(x_[i], i);
    forward<Jet>(d_, xj.data(), joints_, &vertices_, only(), &keypoints_);
  } else {
    std::vector<Eigen::Vector3d> jd, vd, kd;
    forward<double>(d_, x_, jd, &vd, only(), &kd);
    copy_values(jd, joints_);
    copy_values(vd, vertices_);
    copy_values(kd, keypoints_);
  }
  have_jacobians_ = jacobians;
}

void Projector::project(const Vec3J& X, const double* x, Jet* u, Jet* v) const {
  const Vec3J t(Jet(x[cam], cam), Jet(x[cam + 1], cam + 1), Jet(x[cam + 2], cam + 2));
  const Vec3J c = to_camera(X, t);
  *u = f * c(0) / c(2) + cx;
  *v = f * c(1) / c(2) + cy;
}

}  // namespace ks::fit
