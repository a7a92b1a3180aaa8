#pragma once
// The lift's starting point (generate/lift.hpp): the fitted body as its steps see it (the
// subdivided rest mesh, the zero pose, the fit's pose rendered through the fit's camera, the
// head's landmark heights), and the image lookups the steps share.
#include <Eigen/Core>

#include "body/body_model.hpp"
#include "core/image.hpp"
#include "fit/fit_file.hpp"
#include "generate/lift.hpp"
#include "meshrender/meshrender.hpp"
#include "synth/person.hpp"

namespace ks::lift {

// Rest-pose heights (world y, metres) of the head's landmarks.
struct HeadHeights {
  double brow = 0;      // LiftOptions::face_above_eye above the right eye
  double hairline = 0;  // at the nape: LiftOptions::hairline_below_nose below the nose
  double neck = 0;      // the neck joint
};

struct LiftBody {
  SynthPerson person;             // the bare body, subdivided (rest: the shaped body, N vertices)
  Eigen::MatrixXd rest_normals;   // N x 3, of person.rest
  BodyState rest_state;           // the shaped body in the zero pose (rest joints, vertices)
  PosedPerson posed;              // at the fit's pose
  Eigen::MatrixXd posed_normals;  // N x 3
  MeshRenderOutput render;        // posed, through the fit's camera: depth, mask, part labels
  HeadHeights head;
  long vertices() const { return person.rest.rows(); }
};

LiftBody lift_body(const SubjectFit& fit, const LiftOptions& o);

// Whether image point (u, v) (pixels, pixel centres at integer + 0.5) falls in a pixel of the
// 1-channel mask at 0.5 or above; false outside the image.
bool in_mask(const Image& mask, double u, double v);

// Bilinear sample of an image's first three channels (the first, repeated, for grey) at image
// point (u, v) (pixel centres at integer + 0.5), clamped to the image.
Eigen::Vector3d sample_rgb(const Image& img, double u, double v);

}  // namespace ks::lift
