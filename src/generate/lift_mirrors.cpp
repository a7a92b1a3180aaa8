#include "generate/lift_mirrors.hpp"

#include <algorithm>
#include <cmath>

#include "body/joints.hpp"
#include "body/parts.hpp"
#include "core/math.hpp"
#include "mesh/point_grid.hpp"
#include "mesh/trimesh.hpp"

namespace ks::lift {

std::vector<int> mirror_left_right(const Eigen::MatrixXd& V, double cx, double radius) {
  const PointGrid grid(V, radius);
  std::vector<int> out(size_t(V.rows()), -1);
#pragma omp parallel for schedule(static)
  for (long i = 0; i < V.rows(); ++i)
    out[size_t(i)] = grid.nearest(Eigen::Vector3d(2 * cx - V(i, 0), V(i, 1), V(i, 2)), radius);
  return out;
}

std::vector<int> mirror_front_back(const Eigen::MatrixXd& V, const Eigen::MatrixXd& normals,
                                   const SkinJoints& skin_joints, const std::vector<int>& parents,
                                   const Eigen::MatrixXd& joints, double radius) {
  const int J = int(parents.size());
  std::vector<int> child(static_cast<size_t>(J), -1);
  for (int j = 0; j < J; ++j) child[size_t(j)] = first_child(parents, j);
  const PointGrid grid(V, radius);
  std::vector<int> out(size_t(V.rows()), -1);
#pragma omp parallel for schedule(static)
  for (long i = 0; i < V.rows(); ++i) {
    const int j = skin_joints(i, 0);
    Eigen::Vector3d a = joints.row(j).transpose(), b;
    if (child[size_t(j)] >= 0)
      b = joints.row(child[size_t(j)]).transpose();
    else
      b = a + (a - joints.row(std::max(0, parents[size_t(j)])).transpose());
    const Eigen::Vector3d p = V.row(i).transpose(), ab = b - a;
    const double t =
        ab.squaredNorm() > 0 ? std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
    const double cz = a.z() + t * ab.z();
    const Eigen::Vector3d q(p.x(), p.y(), 2 * cz - p.z());
    const double nz = normals(i, 2);
    out[size_t(i)] = grid.nearest(q, radius, [&](int k) { return normals(k, 2) * nz < 0.0; });
  }
  return out;
}

Mirrors find_mirrors(const Eigen::MatrixXd& V, const Eigen::MatrixXi& F,
                     const Eigen::MatrixXd& normals, const SkinJoints& skin_joints,
                     const LiftBody& body, const LiftOptions& o) {
  const double spacing = mean_face_edge_length(V, F);
  const Eigen::MatrixXd& joints = body.rest_state.rest_joints;
  Mirrors m;
  if (o.mirror_left_right)
    m.left_right =
        mirror_left_right(V, joints(smpl_joint::kPelvis, 0), o.left_right_radius_edges * spacing);
  if (o.mirror_front_back)
    m.front_back = mirror_front_back(V, normals, skin_joints, body.person.model->parents, joints,
                                     o.front_back_radius_edges * spacing);
  return m;
}

HeadColours head_colours(const SeenColour& seen, const LiftBody& body, const LiftOptions& o) {
  const long Nb = body.vertices();
  const Eigen::MatrixXd& V0 = body.person.rest;
  const Eigen::MatrixXd& n0 = body.rest_normals;
  const auto head = [&](long i) { return body.person.labels[size_t(i)] == kHeadNeck; };
  HeadColours h;
  {
    std::vector<double> ch[3];
    for (long i = 0; i < Nb; ++i)
      if (head(i) && V0(i, 1) > body.head.brow + o.crown_above_brow &&
          seen.weight(i) > o.hair_min_seen)
        for (int k = 0; k < 3; ++k) ch[k].push_back(seen.colour(i, k));
    for (int k = 0; k < 3; ++k) h.hair(k) = median(ch[k]);
  }
  h.nape = h.hair;
  {
    const double top = body.head.hairline, bottom = top - o.nape_band;
    std::vector<double> ch[3];
    for (long i = 0; i < Nb; ++i)
      if (head(i) && std::abs(n0(i, 0)) > o.nape_side_min_normal_x &&
          std::abs(n0(i, 2)) < o.nape_side_max_normal_z && seen.weight(i) > o.nape_min_seen &&
          V0(i, 1) < top && V0(i, 1) > bottom)
        for (int k = 0; k < 3; ++k) ch[k].push_back(seen.colour(i, k));
    if (!ch[0].empty())
      for (int k = 0; k < 3; ++k) h.nape(k) = median(ch[k]);
  }
  return h;
}

Blend blend_colours(const SeenColour& seen, const Mirrors& mirrors, const HeadColours& head,
                    const LiftBody& body, const LiftOptions& o) {
  const long Nall = seen.colour.rows(), Nb = body.vertices();
  const Eigen::MatrixXd& V0 = body.person.rest;
  const Eigen::MatrixXd& n0 = body.rest_normals;
  const std::vector<int>& lr = mirrors.left_right;
  const std::vector<int>& fb = mirrors.front_back;
  Blend out;
  out.colour.resize(Nall, 3);
  out.weight.resize(Nall);
  int n_seen = 0, n_mirror = 0;
#pragma omp parallel for schedule(static) reduction(+ : n_seen, n_mirror)
  for (long i = 0; i < Nall; ++i) {
    const double ws = seen.weight(i);
    Eigen::Vector3d acc = ws * seen.colour.row(i).transpose();
    double wsum = ws;
    const double rest_w = (1 - ws) * (1 - ws);
    if (!lr.empty() && lr[size_t(i)] >= 0) {
      const double w = o.w_left_right * rest_w * seen.weight(lr[size_t(i)]);
      acc += w * seen.colour.row(lr[size_t(i)]).transpose();
      wsum += w;
    }
    const bool on_head = i < Nb && body.person.labels[size_t(i)] == kHeadNeck;
    const bool back = on_head && n0(i, 2) < o.head_back_normal_z;
    // The back of the head, above the hairline at the nape (about the mouth's height).
    const bool head_back = o.hair_back && back && V0(i, 1) > body.head.hairline;
    // Below it, the nape in the colour the sides of the neck show (not the face mirrored: no
    // lips on the neck).
    const bool nape = o.hair_back && back && !head_back;
    if (head_back || nape) {
      const double w = o.w_head_back * rest_w;
      acc += w * (head_back ? head.hair : head.nape);
      wsum += w;
    } else if (!fb.empty() && fb[size_t(i)] >= 0 && !on_head) {
      // (never the face mirrored onto the back of the head or the nape)
      const double w = o.w_front_back * rest_w * seen.weight(fb[size_t(i)]);
      acc += w * seen.colour.row(fb[size_t(i)]).transpose();
      wsum += w;
    }
    out.weight(i) = wsum;
    if (wsum > 0)
      out.colour.row(i) = (acc / wsum).transpose();
    else
      out.colour.row(i).setZero();
    if (ws >= o.counted_seen)
      ++n_seen;
    else if (wsum >= o.known_weight)
      ++n_mirror;
  }
  out.seen = n_seen;
  out.mirrored = n_mirror;
  return out;
}

}  // namespace ks::lift
