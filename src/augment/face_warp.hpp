#pragma once
// The photo carried onto a frame through the fitted body's surface (a 3D warp): each pixel of the
// frame where the body, posed as in the frame, is seen takes the photo's colour at the same point
// of the body's surface, posed as in the photo, where the photo sees that point. Unlike a 2D
// similarity, this turns the face with the head.
#include <Eigen/Core>

#include "core/camera.hpp"
#include "core/image.hpp"

namespace ks {

// Where the photo sees each vertex of the body at the photo's pose: N x 3 rows (u / width,
// v / height, seen), u, v the vertex's image point (pixel centres at integer + 0.5), seen 1 when
// the vertex faces the camera, is not hidden (depth buffer, `depth_tolerance` metres) and falls
// inside `photo_mask`, else 0.
Eigen::MatrixXd photo_surface(const Eigen::MatrixXd& V_photo, const Eigen::MatrixXi& F,
                              const Camera& photo_camera, const Image& photo_mask,
                              double depth_tolerance = 0.015);

// The photo warped into a frame of `frame_camera`'s size through the body posed as in the frame
// (`V_frame`, the same vertices and faces as photo_surface's): `src` (RGB) and `valid` (1
// channel, 1 where every vertex of the pixel's triangle is seen in the photo, else 0).
void warp_photo_through_body(const Image& photo, const Eigen::MatrixXd& surface,
                             const Eigen::MatrixXd& V_frame, const Eigen::MatrixXi& F,
                             const Camera& frame_camera, Image& src, Image& valid);

}  // namespace ks
