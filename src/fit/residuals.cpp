#include "fit/residuals.hpp"

#include <algorithm>

#include "body/joints.hpp"
#include "core/rotation.hpp"

namespace ks::fit {

bool KeypointResidual::compute(const double* x, std::array<Jet, 2>& r) const {
  Jet u, v;
  pr_.project(ev_.keypoint(k_), x, &u, &v);
  if (!(u.a == u.a) || !(v.a == v.a)) return false;
  r[0] = (u - target_.x()) / unit_;
  r[1] = (v - target_.y()) / unit_;
  return true;
}

bool InsideResidual::compute(const double* x, std::array<Jet, 1>& r) const {
  Jet u, v;
  pr_.project(ev_.vertex(m_), x, &u, &v);
  double du = 0, dv = 0;
  const double val = df_.sample(u.a, v.a, &du, &dv);
  Jet out(val);
  out.v = du * u.v + dv * v.v;
  r[0] = out / unit_;
  return true;
}

bool CoverResidual::compute(const double* x, std::array<Jet, 2>& r) const {
  Jet u, v;
  pr_.project(ev_.vertex(m_), x, &u, &v);
  const Jet du = u - q_.x(), dv = v - q_.y();
  const Jet d = sqrt(du * du + dv * dv + Jet(1e-12));
  Jet s(0.0);
  if (d.a > allowance_) s = Jet(1.0) - allowance_ / d;
  r[0] = s * du / unit_;
  r[1] = s * dv / unit_;
  return true;
}

bool PoseResidual::compute(const double* x, std::array<Jet, 4>& r) const {
  Jet a[3];
  for (int k = 0; k < 3; ++k) a[k] = Jet(x[off_ + k], off_ + k);
  for (int k = 0; k < 3; ++k) a[k] -= jp_.mean(k);
  const Jet tw = a[0] * jp_.axis(0) + a[1] * jp_.axis(1) + a[2] * jp_.axis(2);
  const double ss = std::sqrt(jp_.w_stance) / jp_.sigma_swing;
  for (int k = 0; k < 3; ++k) r[size_t(k)] = ss * (a[k] - tw * jp_.axis(k));
  r[3] = std::sqrt(jp_.w_stance) / jp_.sigma_twist * tw;
  return true;
}

bool LimitResidual::compute(const double* x, std::array<Jet, 3>& r) const {
  const double s = std::sqrt(jp_.w_limits);
  for (int k = 0; k < 3; ++k) {
    const Jet a(x[off_ + k], off_ + k);
    if (a.a > jp_.hi(k))
      r[size_t(k)] = s * (a - jp_.hi(k));
    else if (a.a < jp_.lo(k))
      r[size_t(k)] = s * (a - jp_.lo(k));
    else
      r[size_t(k)] = Jet(0.0);
  }
  return true;
}

bool UprightResidual::compute(const double* x, std::array<Jet, 2>& r) const {
  const Vec3J a(Jet(x[off_], off_), Jet(x[off_ + 1], off_ + 1), Jet(x[off_ + 2], off_ + 2));
  const Eigen::Matrix<Jet, 3, 3> R = axis_angle_to_matrix<Jet>(a);
  r[0] = s_ * R(0, 1);  // x and z of R e_y
  r[1] = s_ * R(2, 1);
  return true;
}

bool GroundResidual::compute(const double*, std::array<Jet, 1>& r) const {
  r[0] = 100.0 * (ev_.joint(a_)(1) - ev_.joint(b_)(1));
  return true;
}

bool ArmTorsoResidual::compute(const double*, std::array<Jet, 1>& r) const {
  const Vec3J a = ev_.joint(smpl_joint::kPelvis), b = ev_.joint(smpl_joint::kNeck),
              p = ev_.joint(joint_);
  const Vec3J ab = b - a;
  Jet t = (p - a).dot(ab) / ab.squaredNorm();
  if (t.a < 0) t = Jet(0.0);
  if (t.a > 1) t = Jet(1.0);
  const Vec3J c = a + t * ab;
  const Jet d = sqrt((p - c).squaredNorm() + Jet(1e-12));
  r[0] = d.a < radius_ ? Jet(s_ * 100.0) * (radius_ - d) : Jet(0.0);
  return true;
}

ShapeResidual::ShapeResidual(int offset, int n, double w, int P)
    : off_(offset), n_(n), s_(std::sqrt(w)) {
  set_num_residuals(n);
  mutable_parameter_block_sizes()->push_back(P);
}

bool ShapeResidual::Evaluate(double const* const* params, double* residuals,
                             double** jacobians) const {
  const int P = parameter_block_sizes()[0];
  for (int b = 0; b < n_; ++b) {
    residuals[b] = s_ * params[0][off_ + b];
    if (jacobians && jacobians[0]) {
      std::fill(jacobians[0] + size_t(b) * P, jacobians[0] + size_t(b + 1) * P, 0.0);
      jacobians[0][size_t(b) * P + off_ + b] = s_;
    }
  }
  return true;
}

}  // namespace ks::fit
