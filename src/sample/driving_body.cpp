#include "sample/driving_body.hpp"

#include <cstdio>

#include "sample/sample.hpp"

namespace ks {

namespace {

constexpr int kCoco18Points = 18;  // the drawn skeleton's points (COCO-18)

}  // namespace

BodyParams DrivingBody::params(const BodyParams& p) const {
  BodyParams q = p;
  q.betas = betas;
  q.expression.resize(0);
  fit_params_to_model(q, *model);
  return q;
}

Skeleton2D DrivingBody::skeleton(const BodyParams& p, const Camera& camera) const {
  return project_skeleton(skeleton_points(sources, body_forward(*model, params(p))), camera);
}

std::optional<DrivingBody> choose_driving_body(const std::string& option, const SubjectFit& fit,
                                               const std::optional<Eigen::VectorXd>& motion_betas,
                                               const SampleNote& note) {
  DrivingBody d;
  if (!option.empty()) {
    d.name = option;
    if (option == "default")
      d.model = std::shared_ptr<const BodyModel>(&default_body_model(), [](const BodyModel*) {});
    else
      d.model = std::make_shared<const BodyModel>(load_body_model(option));
  } else if (motion_betas && fit.model->kind != BodyKind::kDefault) {
    d.model = fit.model;
    d.name = fit.body_model;
  } else if (motion_betas) {
    note(
        "the motion file carries its performer's betas, but the fit uses the default body "
        "model (another shape space): drawing the subject's own skeleton (give --driving-body "
        "MODEL to align the performer's skeleton instead)");
  }
  if (!d.model) return std::nullopt;
  d.betas = motion_betas ? *motion_betas : Eigen::VectorXd::Zero(0);
  if (d.betas.size() > d.model->num_betas) {
    note("the motion's " + std::to_string(d.betas.size()) + " betas cut to the " +
         std::to_string(d.model->num_betas) + " of the driving body model");
    d.betas.conservativeResize(d.model->num_betas);
  }
  d.sources = skeleton_sources(*d.model);
  return d;
}

PoseAlignment align_driving_body(const DrivingBody& driving, const BodyModel& model,
                                 const SkeletonSources& sources, const BodyParams& frame0,
                                 const Camera& camera) {
  BodyParams rest = frame0;
  rest.body_pose.setZero();
  rest.left_hand_pose.setZero();
  rest.right_hand_pose.setZero();
  const Skeleton2D ref =
      project_skeleton(skeleton_points(sources, body_forward(model, rest)), camera);
  const Skeleton2D src = driving.skeleton(rest, camera);
  PoseAlignment a = compute_pose_alignment(ref, src);
  const Skeleton2D ref0 =
      project_skeleton(skeleton_points(sources, body_forward(model, frame0)), camera);
  const Skeleton2D src0 = driving.skeleton(frame0, camera);
  a.offset = (ref0.row(body25::kNeck) - src0.row(body25::kNeck)).transpose();
  return a;
}

std::string alignment_scales_text(const PoseAlignment& a) {
  std::string sc;
  for (int i = 0; i < kAlignParts; ++i) {
    char b[48];
    std::snprintf(b, sizeof b, "%s%s %.3f", i ? ", " : "", kAlignPartNames[size_t(i)],
                  a.scale[size_t(i)]);
    sc += b;
  }
  return sc;
}

Skeleton2D aligned_skeleton(const DrivingBody& driving, const PoseAlignment& alignment,
                            const BodyParams& pose, const SkeletonSources& sources,
                            const BodyState& state, const Camera& camera, AlignmentError& error) {
  const Skeleton2D src = driving.skeleton(pose, camera);
  const Skeleton2D aligned = align_skeleton(src, alignment);
  const Skeleton2D own = project_skeleton(skeleton_points(sources, state), camera);
  for (int i = 0; i < kCoco18Points; ++i) {
    const int k = coco18_to_body25(i);
    error.unaligned += (src.row(k) - own.row(k)).norm();
    error.aligned += (aligned.row(k) - own.row(k)).norm();
    ++error.points;
  }
  return aligned;
}

}  // namespace ks
