#include "augment/face_warp.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "core/error.hpp"
#include "mesh/trimesh.hpp"
#include "meshrender/meshrender.hpp"

namespace ks {

Eigen::MatrixXd photo_surface(const Eigen::MatrixXd& V, const Eigen::MatrixXi& F, const Camera& cam,
                              const Image& mask, double depth_tolerance) {
  if (mask.width != cam.width || mask.height != cam.height || mask.channels < 1)
    throw Error("face warp: the photo's mask is not the camera's size");
  const MeshRenderOutput depth = render_depth(V, F, cam);
  const Eigen::MatrixXd N = vertex_normals(V, F);
  const Eigen::Vector3d eye = cam.centre();
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(V.rows(), 3);
  for (long i = 0; i < V.rows(); ++i) {
    const Eigen::Vector3d p = V.row(i).transpose();
    const Eigen::Vector3d c = cam.to_camera(p);
    if (c.z() <= 0) continue;
    const Eigen::Vector2d uv = cam.project_camera(c);
    S(i, 0) = std::clamp(uv.x() / cam.width, 0.0, 1.0);
    S(i, 1) = std::clamp(uv.y() / cam.height, 0.0, 1.0);
    const int x = int(std::floor(uv.x())), y = int(std::floor(uv.y()));
    if (x < 0 || y < 0 || x >= cam.width || y >= cam.height) continue;
    if (N.row(i).dot(eye - p) <= 0) continue;
    if (c.z() > depth.depth.at(x, y, 0) + depth_tolerance) continue;
    if (mask.at(x, y, 0) < 0.5f) continue;
    S(i, 2) = 1;
  }
  return S;
}

void warp_photo_through_body(const Image& photo, const Eigen::MatrixXd& surface,
                             const Eigen::MatrixXd& V, const Eigen::MatrixXi& F, const Camera& cam,
                             Image& src, Image& valid) {
  if (surface.rows() != V.rows() || surface.cols() != 3)
    throw Error("face warp: the photo surface does not match the frame's vertices");
  MeshRenderInput ri;
  ri.vertices = &V;
  ri.faces = &F;
  ri.colors = &surface;  // interpolated over each triangle: the photo's point of every pixel
  MeshRenderOptions ro;
  ro.cull_backfaces = true;
  const MeshRenderOutput r = render_mesh(cam, ri, ro);
  const int W = cam.width, H = cam.height;
  cv::Mat mx(H, W, CV_32FC1, cv::Scalar(-1)), my(H, W, CV_32FC1, cv::Scalar(-1));
  valid = Image(W, H, 1);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      // Seen only where all three vertices are (the interpolated flag is 1 only then).
      if (r.mask.at(x, y, 0) < 0.999f || r.rgb.at(x, y, 2) < 0.999f) continue;
      mx.at<float>(y, x) = float(r.rgb.at(x, y, 0) * photo.width - 0.5);   // OpenCV: centres
      my.at<float>(y, x) = float(r.rgb.at(x, y, 1) * photo.height - 0.5);  // at integers
      valid.at(x, y, 0) = 1;
    }
  cv::Mat P(photo.height, photo.width, CV_32FC3), out;
  for (int y = 0; y < photo.height; ++y)
    for (int x = 0; x < photo.width; ++x)
      for (int c = 0; c < 3; ++c)
        P.at<cv::Vec3f>(y, x)[c] = photo.at(x, y, std::min(c, photo.channels - 1));
  cv::remap(P, out, mx, my, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  src = Image(W, H, 3);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      for (int c = 0; c < 3; ++c)
        src.at(x, y, c) = valid.at(x, y, 0) > 0 ? out.at<cv::Vec3f>(y, x)[c] : 0.f;
}

}  // namespace ks
