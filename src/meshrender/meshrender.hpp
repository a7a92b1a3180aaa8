#pragma once
// CPU triangle-mesh renderer: depth-tested z-buffer, perspective-correct interpolation, OpenMP over
// screen tiles, optional S x S supersampling. Same camera model as the Gaussian rasterizer
// (ks::Camera, OpenCV convention): pixel centres at integer + 0.5, a point projecting to (u, v)
// lies in column floor(u), row floor(v). With supersampling factor S the samples of pixel (x, y)
// sit at (x + (i + 0.5) / S, y + (j + 0.5) / S), i, j = 0..S-1.
//
// Outputs (each optional):
//  - rgb:    3 channels, the surface colour composited over the background (average of samples).
//  - mask:   1 channel, the covered fraction of the pixel's samples.
//  - depth:  1 channel, camera z of the nearest covered sample (0 where nothing is covered).
//  - normal: 3 channels, camera-space unit normal (average of covered samples, renormalised; zero
//            where nothing is covered). normal_to_rgb() encodes it as a normal-map image.
//  - labels: per pixel the majority per-vertex label over the samples (background counts as a
//            vote for -1), -1 for background.
// Colour comes from per-vertex colours, or a texture sampled bilinearly at interpolated UVs
// (u to the right, v up: v = 0 is the texture's bottom row, as in OBJ), or a constant grey.
// Shading: unlit albedo (default) or ambient + Lambert from a directional light in camera space.
// Triangles crossing the near plane are clipped; both faces are drawn unless cull_backfaces.
// Shared edges are rasterised watertight (a top-left style tie rule: no double coverage, no gaps).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

#include "core/camera.hpp"
#include "core/image.hpp"

namespace ks {

struct MeshRenderOptions {
  int supersample = 1;    // S: S x S samples per pixel (1 = one sample at the pixel centre)
  bool lighting = false;  // false: unlit albedo; true: ambient + Lambert
  double ambient = 0.35;  // lit colour = albedo * (ambient + (1 - ambient) * max(0, n . l))
  Eigen::Vector3d light_dir = Eigen::Vector3d(0.3, -0.5, -1.0);  // camera space, towards light
  Eigen::Vector3d background = Eigen::Vector3d(1.0, 1.0, 1.0);   // RGB in [0, 1]
  bool cull_backfaces = false;
  double near = 1e-3;  // near plane (camera z, metres)
  bool want_rgb = true;
  bool want_mask = true;
  bool want_depth = false;
  bool want_normal = false;
  bool want_labels = false;
  int tile_size = 16;  // in output pixels
};

// What to draw. Pointers are not owned; nullptr = absent. Only vertices and faces are required.
struct MeshRenderInput {
  const Eigen::MatrixXd* vertices = nullptr;  // N x 3, world
  const Eigen::MatrixXi* faces = nullptr;     // M x 3, counter-clockwise seen from outside
  const Eigen::MatrixXd* colors = nullptr;    // N x 3 per-vertex albedo in [0, 1]
  const Eigen::MatrixXd* normals = nullptr;   // N x 3 world (computed from the mesh if absent)
  const std::vector<int>* labels = nullptr;   // N per-vertex labels (e.g. body parts)
  const Image* texture = nullptr;             // RGB texture (used instead of colors if set)
  const Eigen::MatrixXd* uvs = nullptr;       // T x 2 texture coordinates
  const Eigen::MatrixXi* uv_faces = nullptr;  // M x 3 indices into uvs (absent: faces index uvs)
};

struct MeshRenderOutput {
  Image rgb;
  Image mask;
  Image depth;
  Image normal;
  std::vector<int> labels;  // width * height, row-major
  int width = 0;
  int height = 0;
};

// Throws ks::Error on inconsistent inputs (sizes, indices out of range, bad camera or options).
MeshRenderOutput render_mesh(const Camera& camera, const MeshRenderInput& input,
                             const MeshRenderOptions& options = {});

// The depth buffer of a closed surface seen from outside (back faces culled), no colour; with
// `labels`, also the label of the surface seen at each pixel.
MeshRenderOutput render_depth(const Eigen::MatrixXd& vertices, const Eigen::MatrixXi& faces,
                              const Camera& camera, const std::vector<int>* labels = nullptr);

// Normal map image: rgb = 0.5 + 0.5 * (nx, -ny, -nz) (x right, y up, z towards the viewer; a
// surface facing the camera is blue), background where the normal is zero.
Image normal_to_rgb(const Image& normal, const Eigen::Vector3d& background = {1.0, 1.0, 1.0});
// Colour image of a label map with a fixed palette (label -1 = background).
Image labels_to_rgb(const std::vector<int>& labels, int width, int height,
                    const Eigen::Vector3d& background = {1.0, 1.0, 1.0});

}  // namespace ks
