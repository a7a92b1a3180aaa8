#pragma once
// SVAD's identity preservation: in a generated frame where the face is visible, the photo's face
// aligned to it by a similarity transform (from landmarks) and blended in with Poisson image
// editing (OpenCV's seamlessClone), so that every frame carries the photo's face.
#include <Eigen/Core>
#include <vector>

#include "core/image.hpp"

namespace ks {

struct FaceLandmarks {
  // Image points (pixel centres at integer + 0.5) of the same face features in both images,
  // in the same order (nose, eyes, ...; at least 2).
  std::vector<Eigen::Vector2d> points;
};

struct FaceFusionOptions {
  // The face region: an ellipse around the nose with semi-axes these multiples of the distance
  // between the eyes (landmarks 1 and 2), across and down.
  double width = 1.15, height = 1.5;
};

// The similarity (2 x 3: x' = s R x + t) taking `from` onto `to` (least squares).
Eigen::Matrix<double, 2, 3> similarity_2d(const std::vector<Eigen::Vector2d>& from,
                                          const std::vector<Eigen::Vector2d>& to);

// Blends `src` (RGB, the frame's size: the photo already warped onto the frame, by
// warp_face_similarity or augment/face_warp.hpp's warp through the body) into `frame` (changed in
// place) over the face region: the ellipse of FaceFusionOptions around the frame's landmarks
// (nose first, then the two eyes), where `src_valid` and `frame_mask` (1 channel) are set.
// Returns false (frame untouched) when that region would be too small (under 8 px) or leave the
// frame. `region` (optional) receives the region blended.
bool blend_face(const Image& src, const Image& src_valid, Image& frame, const Image& frame_mask,
                const FaceLandmarks& frame_face, const FaceFusionOptions& options = {},
                Image* region = nullptr);

// The photo and its mask warped onto a frame (width x height) by the similarity taking the
// photo's landmarks onto the frame's: `src` RGB, `src_valid` where the warped mask is set.
void warp_face_similarity(const Image& photo, const Image& photo_mask,
                          const FaceLandmarks& photo_face, const FaceLandmarks& frame_face,
                          int width, int height, Image& src, Image& src_valid);

// warp_face_similarity then blend_face: the 2D fusion of SVAD (a frontal face stays frontal; see
// docs/augment.md for where that hurts).
bool fuse_face(const Image& photo, const Image& photo_mask, const FaceLandmarks& photo_face,
               Image& frame, const Image& frame_mask, const FaceLandmarks& frame_face,
               const FaceFusionOptions& options = {}, Image* region = nullptr);

}  // namespace ks
