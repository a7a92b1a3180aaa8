// Density control mesh operations: conforming midpoint splits, link-condition edge collapse,
// naive 3DGS clone/split/prune. All return stencils (see density_ops.hpp).
#include "reconstruct/density_ops.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <tuple>
#include <unordered_map>

#include "core/error.hpp"

namespace ks {

namespace {

using Triplet = Eigen::Triplet<double>;

inline uint64_t edge_key(int a, int b) {
  if (a > b) std::swap(a, b);
  return (uint64_t(uint32_t(a)) << 32) | uint32_t(b);
}

void check_faces(const Eigen::MatrixXi& F, int N, const char* what) {
  if (F.rows() > 0 && (F.cols() != 3 || F.minCoeff() < 0 || F.maxCoeff() >= N))
    throw Error(std::string(what) + ": face indices out of range for " + std::to_string(N) +
                " vertices");
}

}  // namespace

MeshEdit split_faces(const Eigen::MatrixXi& F, int N, const std::vector<uint8_t>& selected) {
  check_faces(F, N, "split_faces");
  const int M = int(F.rows());
  if (int(selected.size()) != M) throw Error("split_faces: selection size differs from faces");
  // Edge ids per face corner: edge k of face f joins F(f,k) and F(f,(k+1)%3).
  std::unordered_map<uint64_t, int> edge_id;
  edge_id.reserve(size_t(M) * 2);
  std::vector<int> fe(3 * size_t(M));
  std::vector<std::pair<int, int>> edges;
  for (int f = 0; f < M; ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = F(f, k), b = F(f, (k + 1) % 3);
      auto [it, inserted] = edge_id.emplace(edge_key(a, b), int(edges.size()));
      if (inserted) edges.push_back({std::min(a, b), std::max(a, b)});
      fe[3 * size_t(f) + k] = it->second;
    }
  std::vector<uint8_t> marked(edges.size(), 0);
  for (int f = 0; f < M; ++f)
    if (selected[f])
      for (int k = 0; k < 3; ++k) marked[fe[3 * size_t(f) + k]] = 1;
  // Closure: faces with two split edges become full splits.
  for (bool changed = true; changed;) {
    changed = false;
    for (int f = 0; f < M; ++f) {
      int c = 0;
      for (int k = 0; k < 3; ++k) c += marked[fe[3 * size_t(f) + k]];
      if (c == 2) {
        for (int k = 0; k < 3; ++k) marked[fe[3 * size_t(f) + k]] = 1;
        changed = true;
      }
    }
  }
  std::vector<int> mid(edges.size(), -1);
  int next = N;
  for (size_t e = 0; e < edges.size(); ++e)
    if (marked[e]) mid[e] = next++;
  const int N_new = next;

  std::vector<Eigen::Vector3i> out;
  out.reserve(size_t(M) + 3 * std::count(marked.begin(), marked.end(), 1));
  for (int f = 0; f < M; ++f) {
    const int* e = &fe[3 * size_t(f)];
    const int c = marked[e[0]] + marked[e[1]] + marked[e[2]];
    const int a = F(f, 0), b = F(f, 1), cc = F(f, 2);
    if (c == 0) {
      out.push_back({a, b, cc});
    } else if (c == 3) {
      const int m0 = mid[e[0]], m1 = mid[e[1]], m2 = mid[e[2]];
      out.push_back({a, m0, m2});
      out.push_back({m0, b, m1});
      out.push_back({m2, m1, cc});
      out.push_back({m0, m1, m2});
    } else {  // c == 1: bisect from the opposite corner
      int k = 0;
      while (!marked[e[k]]) ++k;
      const int p = F(f, k), q = F(f, (k + 1) % 3), r = F(f, (k + 2) % 3), m = mid[e[k]];
      out.push_back({p, m, r});
      out.push_back({m, q, r});
    }
  }
  MeshEdit edit;
  edit.faces.resize(Eigen::Index(out.size()), 3);
  for (size_t i = 0; i < out.size(); ++i) edit.faces.row(Eigen::Index(i)) = out[i].transpose();
  std::vector<Triplet> trip;
  trip.reserve(size_t(N) + 2 * size_t(N_new - N));
  for (int v = 0; v < N; ++v) trip.emplace_back(v, v, 1.0);
  for (size_t e = 0; e < edges.size(); ++e)
    if (mid[e] >= 0) {
      trip.emplace_back(mid[e], edges[e].first, 0.5);
      trip.emplace_back(mid[e], edges[e].second, 0.5);
      edit.new_rows.push_back(mid[e]);
    }
  edit.S.resize(N_new, N);
  edit.S.setFromTriplets(trip.begin(), trip.end());
  edit.old_to_new.resize(N);
  for (int v = 0; v < N; ++v) edit.old_to_new[v] = v;
  return edit;
}

std::vector<uint8_t> faces_around_vertices(const Eigen::MatrixXi& F,
                                           const std::vector<uint8_t>& vsel) {
  std::vector<uint8_t> out(F.rows(), 0);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int v = F(f, k);
      if (v >= 0 && v < int(vsel.size()) && vsel[v]) out[f] = 1;
    }
  return out;
}

MeshEdit collapse_vertices(const Eigen::MatrixXd& V, const Eigen::MatrixXi& F,
                           const std::vector<uint8_t>& cand, const CollapseOptions& opt) {
  const int N = int(V.rows());
  const int M = int(F.rows());
  check_faces(F, N, "collapse_vertices");
  if (int(cand.size()) != N) throw Error("collapse_vertices: candidate mask size differs from V");
  // Incidence and adjacency.
  std::vector<std::vector<int>> vf(N), adj(N);
  std::unordered_map<uint64_t, int> edge_faces;
  edge_faces.reserve(size_t(M) * 2);
  for (int f = 0; f < M; ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = F(f, k), b = F(f, (k + 1) % 3);
      vf[a].push_back(f);
      adj[a].push_back(b);
      adj[b].push_back(a);
      ++edge_faces[edge_key(a, b)];
    }
  for (auto& n : adj) {
    std::sort(n.begin(), n.end());
    n.erase(std::unique(n.begin(), n.end()), n.end());
  }
  std::vector<uint8_t> boundary(N, 0);
  for (const auto& [key, count] : edge_faces)
    if (count != 2) {
      boundary[int(key >> 32)] = 1;
      boundary[int(key & 0xffffffffu)] = 1;
    }
  // Candidate edges, shortest first.
  std::vector<std::tuple<double, int, int>> order;  // (length, v removed, u kept)
  for (int v = 0; v < N; ++v)
    if (cand[v])
      for (int u : adj[v]) order.emplace_back((V.row(u) - V.row(v)).norm(), v, u);
  std::sort(order.begin(), order.end());

  std::vector<uint8_t> locked(N, 0), face_dead(M, 0);
  std::vector<int> target(N, -1);  // removed vertex -> kept vertex
  std::vector<uint8_t> midpoint(N, 0);
  int done = 0;
  auto face_has = [&](int f, int x) { return F(f, 0) == x || F(f, 1) == x || F(f, 2) == x; };
  auto ring_free = [&](int x) {
    if (locked[x]) return false;
    for (int y : adj[x])
      if (locked[y]) return false;
    return true;
  };
  for (const auto& [len, v, u] : order) {
    (void)len;
    if (opt.max_collapses >= 0 && done >= opt.max_collapses) break;
    if (target[v] >= 0 || target[u] >= 0) continue;
    if (boundary[u] || boundary[v]) continue;
    if (!ring_free(u) || !ring_free(v)) continue;
    // The two faces of the edge and their opposite vertices.
    int opp[2], nf = 0;
    for (int f : vf[v])
      if (face_has(f, u)) {
        if (nf < 2) opp[nf] = F(f, 0) + F(f, 1) + F(f, 2) - u - v;
        ++nf;
      }
    if (nf != 2) continue;
    // Link condition: exactly the two opposite vertices are common neighbours.
    std::vector<int> common;
    std::set_intersection(adj[u].begin(), adj[u].end(), adj[v].begin(), adj[v].end(),
                          std::back_inserter(common));
    if (common.size() != 2) continue;
    if (adj[opp[0]].size() <= 3 || adj[opp[1]].size() <= 3) continue;
    if (adj[u].size() + adj[v].size() < 4 + 3 + 2) continue;  // merged valence >= 3
    bool fold = false;
    for (int f : vf[u])
      if (face_has(f, opp[0]) && face_has(f, opp[1]) && !face_has(f, v)) fold = true;
    for (int f : vf[v])
      if (face_has(f, opp[0]) && face_has(f, opp[1]) && !face_has(f, u)) fold = true;
    if (fold) continue;
    // Normal check for every face that survives around u and v.
    const bool both = cand[u] != 0;
    const Eigen::Vector3d p = both ? Eigen::Vector3d(0.5 * (V.row(u) + V.row(v)).transpose())
                                   : Eigen::Vector3d(V.row(u).transpose());
    bool flips = false;
    for (int x : {u, v}) {
      for (int f : vf[x]) {
        if (face_has(f, u) && face_has(f, v)) continue;
        Eigen::Vector3d P[3], Q[3];
        for (int k = 0; k < 3; ++k) {
          P[k] = V.row(F(f, k)).transpose();
          Q[k] = (F(f, k) == u || F(f, k) == v) ? p : P[k];
        }
        const Eigen::Vector3d n0 = (P[1] - P[0]).cross(P[2] - P[0]);
        const Eigen::Vector3d n1 = (Q[1] - Q[0]).cross(Q[2] - Q[0]);
        const double l0 = n0.norm(), l1 = n1.norm();
        if (l1 <= 1e-12 * std::max(1.0, l0) ||
            (l0 > 0 && n0.dot(n1) < opt.min_normal_dot * l0 * l1))
          flips = true;
      }
    }
    if (flips) continue;
    // Collapse v into u.
    target[v] = u;
    midpoint[u] = both;
    for (int f : vf[v])
      if (face_has(f, u)) face_dead[f] = 1;
    for (int x : {u, v}) {
      locked[x] = 1;
      for (int y : adj[x]) locked[y] = 1;
    }
    ++done;
  }
  // Compact.
  MeshEdit edit;
  edit.old_to_new.assign(N, -1);
  int n_new = 0;
  for (int x = 0; x < N; ++x)
    if (target[x] < 0) edit.old_to_new[x] = n_new++;
  std::vector<Triplet> trip;
  for (int x = 0; x < N; ++x) {
    if (target[x] >= 0) continue;
    const int r = edit.old_to_new[x];
    trip.emplace_back(r, x, midpoint[x] ? 0.5 : 1.0);  // the other half is added below
  }
  for (int x = 0; x < N; ++x)
    if (target[x] >= 0 && midpoint[target[x]])
      trip.emplace_back(edit.old_to_new[target[x]], x, 0.5);
  for (int x = 0; x < N; ++x)
    if (target[x] >= 0) edit.old_to_new[x] = -1;
  edit.S.resize(n_new, N);
  edit.S.setFromTriplets(trip.begin(), trip.end());
  std::vector<Eigen::Vector3i> out;
  out.reserve(M);
  for (int f = 0; f < M; ++f) {
    if (face_dead[f]) continue;
    Eigen::Vector3i t;
    for (int k = 0; k < 3; ++k) {
      int x = F(f, k);
      if (target[x] >= 0) x = target[x];
      t[k] = edit.old_to_new[x];
    }
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;  // cannot happen (link condition)
    out.push_back(t);
  }
  edit.faces.resize(Eigen::Index(out.size()), 3);
  for (size_t i = 0; i < out.size(); ++i) edit.faces.row(Eigen::Index(i)) = out[i].transpose();
  return edit;
}

NaiveEdit naive_densify(const Eigen::MatrixXd& anchors, const Eigen::MatrixXi& F,
                        const std::vector<float>& grad, const Gaussians& g,
                        const NaiveOptions& opt) {
  const int N = int(anchors.rows());
  check_faces(F, N, "naive_densify");
  if (int(g.size()) != N || int(grad.size()) != N)
    throw Error("naive_densify: Gaussians / gradients do not match the vertex count");
  // Scene extent: radius of the anchors around their centroid.
  const Eigen::RowVector3d c =
      N > 0 ? Eigen::RowVector3d(anchors.colwise().mean()) : Eigen::RowVector3d::Zero();
  double extent = 0;
  for (int i = 0; i < N; ++i) extent = std::max(extent, (anchors.row(i) - c).norm());
  enum Kind : uint8_t { kKeep, kPrune, kClone, kSplit };
  std::vector<uint8_t> kind(N, kKeep);
  NaiveEdit out;
  for (int i = 0; i < N; ++i) {
    const float opacity = 1.f / (1.f + std::exp(-g.opacity_logits[i]));
    const float smax =
        std::exp(std::max({g.log_scales[3 * i], g.log_scales[3 * i + 1], g.log_scales[3 * i + 2]}));
    if (opacity < opt.prune_opacity || smax > opt.prune_scale * extent) {
      kind[i] = kPrune;
      ++out.pruned;
    } else if (grad[i] > opt.grad_threshold) {
      if (smax <= opt.percent_dense * extent) {
        kind[i] = kClone;
        ++out.cloned;
      } else {
        kind[i] = kSplit;
        ++out.split;
      }
    }
  }
  MeshEdit& e = out.edit;
  e.old_to_new.assign(N, -1);
  int n = 0;
  for (int i = 0; i < N; ++i)
    if (kind[i] != kPrune) e.old_to_new[i] = n++;
  std::vector<Triplet> trip;
  for (int i = 0; i < N; ++i)
    if (e.old_to_new[i] >= 0) trip.emplace_back(e.old_to_new[i], i, 1.0);
  std::mt19937_64 rng(opt.seed);
  std::normal_distribution<double> normal;
  auto sample = [&](int i, double scale_mult) {
    const Eigen::Quaterniond q(g.quats[4 * i], g.quats[4 * i + 1], g.quats[4 * i + 2],
                               g.quats[4 * i + 3]);
    const Eigen::Matrix3d R =
        q.norm() > 0 ? q.normalized().toRotationMatrix() : Eigen::Matrix3d::Identity();
    Eigen::Vector3d z(normal(rng), normal(rng), normal(rng));
    for (int k = 0; k < 3; ++k) z[k] *= std::exp(double(g.log_scales[3 * i + k])) * scale_mult;
    return Eigen::Vector3d(anchors.row(i).transpose() + R * z);
  };
  const float split_delta = -std::log(1.6f);  // 3DGS: scale / (0.8 * 2)
  std::vector<std::pair<int, float>> new_delta;
  for (int i = 0; i < N; ++i) {
    if (kind[i] == kClone) {
      const int r = n++;
      trip.emplace_back(r, i, 1.0);
      e.new_rows.push_back(r);
      out.moved_rows.push_back(r);
      out.positions.push_back(sample(i, opt.clone_jitter));
      new_delta.push_back({r, 0.f});
    } else if (kind[i] == kSplit) {
      const int r = n++;
      trip.emplace_back(r, i, 1.0);
      e.new_rows.push_back(r);
      out.moved_rows.push_back(e.old_to_new[i]);
      out.positions.push_back(sample(i, 1.0));
      out.moved_rows.push_back(r);
      out.positions.push_back(sample(i, 1.0));
      new_delta.push_back({e.old_to_new[i], split_delta});
      new_delta.push_back({r, split_delta});
    }
  }
  e.S.resize(n, N);
  e.S.setFromTriplets(trip.begin(), trip.end());
  out.log_scale_delta.assign(n, 0.f);
  for (auto [r, d] : new_delta) out.log_scale_delta[r] = d;
  std::vector<Eigen::Vector3i> faces;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    Eigen::Vector3i t;
    bool ok = true;
    for (int k = 0; k < 3; ++k) {
      t[k] = e.old_to_new[F(f, k)];
      ok = ok && t[k] >= 0;
    }
    if (ok) faces.push_back(t);
  }
  e.faces.resize(Eigen::Index(faces.size()), 3);
  for (size_t i = 0; i < faces.size(); ++i) e.faces.row(Eigen::Index(i)) = faces[i].transpose();
  return out;
}

MeshEdit compose(const MeshEdit& a, const MeshEdit& b) {
  if (b.S.cols() != a.S.rows()) throw Error("compose: stencil sizes do not chain");
  MeshEdit out;
  out.S = (b.S * a.S).pruned();
  out.faces = b.faces;
  out.old_to_new.assign(a.old_to_new.size(), -1);
  for (size_t i = 0; i < a.old_to_new.size(); ++i)
    if (a.old_to_new[i] >= 0) out.old_to_new[i] = b.old_to_new[a.old_to_new[i]];
  out.new_rows = b.new_rows;
  for (int r : a.new_rows)
    if (b.old_to_new[r] >= 0) out.new_rows.push_back(b.old_to_new[r]);
  std::sort(out.new_rows.begin(), out.new_rows.end());
  return out;
}

}  // namespace ks
