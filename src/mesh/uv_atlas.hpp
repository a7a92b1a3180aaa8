#pragma once
// A UV atlas laid out for any triangle mesh, so a colour can be baked into one texture
// (docs/export.md: the glTF export's base-colour texture).
//   charts   faces grown breadth-first from a seed face across shared edges while their normals
//            stay within `max_normal_angle_deg` of the seed's; each chart is projected
//            orthographically onto the plane of its seed's normal (every face then keeps its
//            orientation), turned to its principal axes
//   packing  the charts' rectangles (plus a gutter of `padding` texels on every side) in shelves,
//            tallest first (each chart turned to lie wider than tall), into a square texture of
//            a power-of-two side: the smallest that holds the charts at `texels_per_edge` texels
//            along the mesh's mean edge (a lower scale where even `max_size` would not), the
//            scale then raised while they still fit (`fill`)
// A mesh vertex on a chart border is copied once per chart that holds it: `source` says which.
// UVs follow glTF: (0, 0) is the image's top-left corner, v grows downwards, a texel (x, y) has
// its centre at ((x + 0.5) / size, (y + 0.5) / size).
#include <Eigen/Core>
#include <vector>

namespace ks {

struct UvAtlasOptions {
  double max_normal_angle_deg = 50;  // a chart's faces stay within this angle of its seed's normal
  double texels_per_edge = 2.0;      // texels along the mesh's mean edge length
  int padding = 2;                   // texels of gutter on each side of a chart
  int min_size = 256, max_size = 4096;  // the texture's side (a power of two) stays in this range
  bool fill = true;  // then raise the scale while the charts still fit that side (free texels)
};

struct UvAtlas {
  int size = 0;                 // the texture is size x size texels
  double texels_per_metre = 0;  // the scale used
  Eigen::MatrixXi faces;        // F x 3, indices into the atlas's vertices
  std::vector<int> source;      // per atlas vertex: the mesh vertex it copies
  std::vector<float> uv;        // 2 per atlas vertex, in [0, 1]
  std::vector<int> face_chart;  // per face: its chart
  int charts = 0;
};

// Throws ks::Error for an empty mesh, a face naming a vertex out of range, or options out of
// range (angle outside (0, 90), texels_per_edge <= 0, padding < 0, sizes not powers of two).
UvAtlas build_uv_atlas(const Eigen::MatrixXd& V, const Eigen::MatrixXi& F,
                       const UvAtlasOptions& opt = {});

}  // namespace ks
