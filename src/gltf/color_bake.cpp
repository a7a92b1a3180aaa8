#include "gltf/color_bake.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "body/skin_weights.hpp"
#include "core/error.hpp"
#include "mesh/point_grid.hpp"
#include "mesh/trimesh.hpp"
#include "raster/sh.hpp"

namespace ks {
namespace {

float sigmoid(float x) {
  return 1.f / (1.f + std::exp(-x));
}

// Grid cell for n points spread over their bounding box (about their spacing).
double grid_cell(const Eigen::MatrixXd& P) {
  const Eigen::Vector3d ext = P.colwise().maxCoeff() - P.colwise().minCoeff();
  const double vol = std::max(ext.x(), 1e-6) * std::max(ext.y(), 1e-6) * std::max(ext.z(), 1e-6);
  return std::max(1e-6, std::cbrt(vol / double(std::max<Eigen::Index>(P.rows(), 1))));
}

// The nearest point of the grid's set, however far (the search radius doubles until one is found).
int nearest_any(const PointGrid& grid, const Eigen::Vector3d& q, double cell) {
  for (double r = 2 * cell;; r *= 2) {
    const int i = grid.nearest(q, r);
    if (i >= 0 || r > 1e4) return i;
  }
}

void check_avatar(const Avatar& a) {
  const size_t N = a.gaussians.size();
  if (a.template_vertices.rows() == 0) throw Error("gltf: the avatar has no template surface");
  if (N == 0) throw Error("gltf: the avatar has no Gaussians to bake colours from");
  if (a.anchors.size() != 3 * N || a.skin_joints.size() != 4 * N || a.skin_weights.size() != 4 * N)
    throw Error("gltf: the avatar's anchors or skin weights do not match its Gaussians");
}

}  // namespace

Eigen::Vector3f band0_srgb(const Gaussians& g, size_t i) {
  const int K = g.coeffs();
  Eigen::Vector3f c;
  for (int k = 0; k < 3; ++k)
    c[k] = std::clamp(float(g.sh[i * size_t(K) * 3 + size_t(k)] * sh::kC0 + 0.5), 0.f, 1.f);
  return c;
}

std::vector<std::vector<int>> gaussians_per_vertex(const Avatar& a) {
  check_avatar(a);
  const long V = a.template_vertices.rows();
  const size_t N = a.gaussians.size();
  Eigen::MatrixXd anchors(long(N), 3);
  for (size_t i = 0; i < N; ++i)
    for (int k = 0; k < 3; ++k) anchors(long(i), k) = a.anchors[3 * i + size_t(k)];
  const double vcell = grid_cell(a.template_vertices), acell = grid_cell(anchors);
  const PointGrid vgrid(a.template_vertices, vcell);
  std::vector<std::vector<int>> members(static_cast<size_t>(V));
  for (size_t i = 0; i < N; ++i) {
    const int v = nearest_any(vgrid, anchors.row(long(i)).transpose(), vcell);
    if (v >= 0) members[size_t(v)].push_back(int(i));
  }
  const PointGrid agrid(anchors, acell);
  for (long v = 0; v < V; ++v)
    if (members[size_t(v)].empty()) {
      const int i = nearest_any(agrid, a.template_vertices.row(v).transpose(), acell);
      if (i >= 0) members[size_t(v)].push_back(i);
    }
  return members;
}

BakedVertexAttributes bake_vertex_attributes(const Avatar& a) {
  return bake_vertex_attributes(a, gaussians_per_vertex(a));
}

BakedVertexAttributes bake_vertex_attributes(const Avatar& a,
                                             const std::vector<std::vector<int>>& members) {
  check_avatar(a);
  const long V = a.template_vertices.rows();
  if (members.size() != size_t(V))
    throw Error("gltf: the Gaussians per vertex do not match the avatar's template");
  BakedVertexAttributes out;
  out.srgb.resize(3 * size_t(V));
  out.joints.resize(4 * size_t(V));
  out.weights.resize(4 * size_t(V));
  std::vector<JointWeight> entries;
  for (long v = 0; v < V; ++v) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    double wsum = 0;
    entries.clear();
    for (int i : members[size_t(v)]) {
      const double w = std::max(1e-6, double(sigmoid(a.gaussians.opacity_logits[size_t(i)])));
      c += w * band0_srgb(a.gaussians, size_t(i)).cast<double>();
      wsum += w;
      for (int s = 0; s < kAvatarSkinK; ++s)
        add_joint_weight(entries, a.skin_joints[4 * size_t(i) + size_t(s)],
                         w * a.skin_weights[4 * size_t(i) + size_t(s)]);
    }
    if (wsum > 0) c /= wsum;
    for (int k = 0; k < 3; ++k) out.srgb[3 * size_t(v) + size_t(k)] = float(c[k]);
    int jj[4];
    reduce_top_k(entries, 4, jj, &out.weights[4 * size_t(v)]);
    for (int s = 0; s < 4; ++s) out.joints[4 * size_t(v) + size_t(s)] = jj[s];
  }
  return out;
}

Eigen::MatrixXd splat_surface(const Avatar& a, const std::vector<std::vector<int>>& members) {
  check_avatar(a);
  const Eigen::MatrixXd& T = a.template_vertices;
  if (members.size() != size_t(T.rows()))
    throw Error("gltf: the Gaussians per vertex do not match the avatar's template");
  const Eigen::MatrixXd normals = vertex_normals(T, a.template_faces);
  const Gaussians& g = a.gaussians;
  Eigen::MatrixXd out = T;
  for (long v = 0; v < T.rows(); ++v) {
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    double wsum = 0, reach = 0;
    for (int i : members[size_t(v)]) {
      const size_t n = size_t(i);
      const double alpha = sigmoid(g.opacity_logits[n]), w = std::max(1e-6, alpha);
      double s[3];
      for (int k = 0; k < 3; ++k) s[k] = std::exp(double(g.log_scales[3 * n + size_t(k)]));
      std::sort(s, s + 3);
      const double radius = 0.5 * (s[1] + s[2]);
      const double r = alpha > 0.5 ? radius * std::sqrt(2 * std::log(2 * alpha)) : 0.0;
      centre += w * Eigen::Vector3d(g.means[3 * n], g.means[3 * n + 1], g.means[3 * n + 2]);
      reach += w * r;
      wsum += w;
    }
    if (!(wsum > 0)) continue;
    Eigen::Vector3d nrm = normals.row(v).transpose();
    if (!nrm.allFinite()) nrm.setZero();
    out.row(v) = (centre / wsum + (reach / wsum) * nrm).transpose();
  }
  return out;
}

namespace {

// The Gaussians a texel's colour is drawn from, in the form the bake reads: rotation, inverse
// scales, opacity and band-0 colour.
struct Splat {
  Eigen::Vector3f mean, inv_scale, srgb;
  Eigen::Matrix3f rot;  // columns: the Gaussian's axes
  float opacity;
};

std::vector<Splat> splats_of(const Gaussians& g) {
  std::vector<Splat> out(g.size());
  for (size_t i = 0; i < g.size(); ++i) {
    Splat& s = out[i];
    for (int k = 0; k < 3; ++k) {
      s.mean[k] = g.means[3 * i + size_t(k)];
      s.inv_scale[k] = std::exp(-g.log_scales[3 * i + size_t(k)]);
    }
    Eigen::Quaternionf q(g.quats[4 * i], g.quats[4 * i + 1], g.quats[4 * i + 2],
                         g.quats[4 * i + 3]);
    const float n = q.norm();
    s.rot = n > 0 && std::isfinite(n) ? Eigen::Matrix3f(q.normalized().toRotationMatrix())
                                      : Eigen::Matrix3f::Identity();
    s.opacity = sigmoid(g.opacity_logits[i]);
    s.srgb = band0_srgb(g, i);
  }
  return out;
}

// Texels with no colour take the mean of their coloured 8-neighbours, ring by ring.
void dilate(Image& img, std::vector<char>& filled, int rings) {
  const int W = img.width, H = img.height;
  for (int r = 0; r < rings; ++r) {
    std::vector<char> next = filled;
    Image out = img;
#pragma omp parallel for schedule(static)
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        if (filled[size_t(y) * W + x]) continue;
        float c[3] = {0, 0, 0};
        int n = 0;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int xx = x + dx, yy = y + dy;
            if (xx < 0 || yy < 0 || xx >= W || yy >= H || !filled[size_t(yy) * W + xx]) continue;
            for (int k = 0; k < 3; ++k) c[k] += img.at(xx, yy, k);
            ++n;
          }
        if (n == 0) continue;
        for (int k = 0; k < 3; ++k) out.at(x, y, k) = c[k] / float(n);
        next[size_t(y) * W + x] = 1;
      }
    img = std::move(out);
    filled = std::move(next);
  }
}

}  // namespace

BakedTexture bake_texture(const Avatar& a, const Eigen::MatrixXd& V,
                          const BakedVertexAttributes& vc,
                          const std::vector<std::vector<int>>& members,
                          const TextureBakeOptions& opt) {
  check_avatar(a);
  if (V.rows() != a.template_vertices.rows() || V.cols() != 3)
    throw Error("gltf: the surface to bake onto does not match the avatar's template");
  const Eigen::MatrixXi& F = a.template_faces;
  if (vc.srgb.size() != 3 * size_t(V.rows()) || members.size() != size_t(V.rows()))
    throw Error("gltf: the vertex colours do not match the avatar's template");
  BakedTexture out;
  out.atlas = build_uv_atlas(a.template_vertices, F, opt.atlas);  // charts on the smooth template
  const UvAtlas& at = out.atlas;
  const int S = at.size;
  // Which face each texel centre lies in (the last one drawn where faces touch).
  std::vector<int> owner(size_t(S) * S, -1);
  for (long f = 0; f < F.rows(); ++f) {
    Eigen::Vector2d p[3];
    for (int k = 0; k < 3; ++k)
      p[k] = Eigen::Vector2d(at.uv[2 * size_t(at.faces(f, k))] * S,
                             at.uv[2 * size_t(at.faces(f, k)) + 1] * S);
    const double area =
        (p[1] - p[0]).x() * (p[2] - p[0]).y() - (p[1] - p[0]).y() * (p[2] - p[0]).x();
    if (!(std::abs(area) > 1e-12)) continue;
    const int x0 = std::max(0, int(std::floor(std::min({p[0].x(), p[1].x(), p[2].x()}))));
    const int x1 = std::min(S - 1, int(std::ceil(std::max({p[0].x(), p[1].x(), p[2].x()}))));
    const int y0 = std::max(0, int(std::floor(std::min({p[0].y(), p[1].y(), p[2].y()}))));
    const int y1 = std::min(S - 1, int(std::ceil(std::max({p[0].y(), p[1].y(), p[2].y()}))));
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const Eigen::Vector2d q(x + 0.5, y + 0.5);
        double b[3];
        for (int k = 0; k < 3; ++k) {
          const Eigen::Vector2d e0 = p[(k + 1) % 3] - q, e1 = p[(k + 2) % 3] - q;
          b[k] = (e0.x() * e1.y() - e0.y() * e1.x()) / area;
        }
        if (b[0] >= -1e-9 && b[1] >= -1e-9 && b[2] >= -1e-9) owner[size_t(y) * S + x] = int(f);
      }
  }
  // A face smaller than a texel covers no texel centre: it takes the texels under its centroid
  // and its corners that no face covers, so that every face has a colour where it samples.
  for (long f = 0; f < F.rows(); ++f) {
    double px[4] = {0, 0, 0, 0}, py[4] = {0, 0, 0, 0};
    for (int k = 0; k < 3; ++k) {
      px[k] = at.uv[2 * size_t(at.faces(f, k))] * S;
      py[k] = at.uv[2 * size_t(at.faces(f, k)) + 1] * S;
      px[3] += px[k] / 3;
      py[3] += py[k] / 3;
    }
    for (int k = 3; k >= 0; --k) {
      const int tx = std::clamp(int(px[k]), 0, S - 1), ty = std::clamp(int(py[k]), 0, S - 1);
      int& o = owner[size_t(ty) * S + size_t(tx)];
      if (o < 0) o = int(f);
    }
  }
  // The Gaussians each face draws from: those of its vertices and of their neighbours.
  const auto adj = vertex_adjacency(F, int(V.rows()));
  const std::vector<Splat> splats = splats_of(a.gaussians);
  out.image = Image(S, S, 3);
  std::vector<char> filled(size_t(S) * S, 0);
  const float w0 = opt.vertex_colour_weight;
#pragma omp parallel for schedule(dynamic, 16)
  for (int y = 0; y < S; ++y) {
    std::vector<int> cand;
    long cached = -1;
    for (int x = 0; x < S; ++x) {
      const int f = owner[size_t(y) * S + x];
      if (f < 0) continue;
      if (f != cached) {
        cand.clear();
        for (int k = 0; k < 3; ++k) {
          const int v = F(f, k);
          for (int i : members[size_t(v)]) cand.push_back(i);
          for (int u : adj[size_t(v)])
            for (int i : members[size_t(u)]) cand.push_back(i);
        }
        std::sort(cand.begin(), cand.end());
        cand.erase(std::unique(cand.begin(), cand.end()), cand.end());
        cached = f;
      }
      // The texel's surface point and the face's normal.
      Eigen::Vector2d p[3];
      for (int k = 0; k < 3; ++k)
        p[k] = Eigen::Vector2d(at.uv[2 * size_t(at.faces(f, k))] * S,
                               at.uv[2 * size_t(at.faces(f, k)) + 1] * S);
      const double area =
          (p[1] - p[0]).x() * (p[2] - p[0]).y() - (p[1] - p[0]).y() * (p[2] - p[0]).x();
      const Eigen::Vector2d q(x + 0.5, y + 0.5);
      Eigen::Vector3d pt = Eigen::Vector3d::Zero(), vcol = Eigen::Vector3d::Zero();
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector2d e0 = p[(k + 1) % 3] - q, e1 = p[(k + 2) % 3] - q;
        const double b = std::clamp((e0.x() * e1.y() - e0.y() * e1.x()) / area, 0.0, 1.0);
        const int v = F(f, k);
        pt += b * V.row(v).transpose();
        for (int c = 0; c < 3; ++c) vcol[c] += b * vc.srgb[3 * size_t(v) + size_t(c)];
      }
      const Eigen::Vector3d e1 = V.row(F(f, 1)) - V.row(F(f, 0)),
                            e2 = V.row(F(f, 2)) - V.row(F(f, 0));
      const Eigen::Vector3d nd = e1.cross(e2);
      const Eigen::Vector3f n = nd.norm() > 1e-14 ? Eigen::Vector3f(nd.normalized().cast<float>())
                                                  : Eigen::Vector3f::Zero();
      const Eigen::Vector3f pf = pt.cast<float>();
      Eigen::Vector3f c = w0 * vcol.cast<float>();
      float wsum = w0;
      for (int i : cand) {
        const Splat& s = splats[size_t(i)];
        Eigen::Vector3f d = pf - s.mean;
        d -= d.dot(n) * n;
        const Eigen::Vector3f l = (s.rot.transpose() * d).cwiseProduct(s.inv_scale);
        const float m = l.squaredNorm();
        if (m > 18.f) continue;  // beyond 6 sigma
        const float w = s.opacity * std::exp(-0.5f * m);
        c += w * s.srgb;
        wsum += w;
      }
      c /= wsum;
      for (int k = 0; k < 3; ++k) out.image.at(x, y, k) = std::clamp(c[k], 0.f, 1.f);
      filled[size_t(y) * S + x] = 1;
    }
  }
  dilate(out.image, filled, opt.atlas.padding + 1);
  return out;
}

}  // namespace ks
