#pragma once
// Test-only helpers: random small body models in the smplx .npz layout, built here from scratch,
// and an independent float64 reference of SMPL's forward model written with plain loops.
#include <cmath>
#include <cstdint>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "io/npz.hpp"

namespace ks::testing {

// A model as plain arrays (the values the file holds, read back as double).
struct RefModel {
  int V = 0, J = 0, S = 0, F = 0;
  std::vector<double> vt;         // V*3
  std::vector<int> faces;         // F*3
  std::vector<double> shapedirs;  // V*3*S
  std::vector<double> posedirs;   // V*3*P
  std::vector<double> jreg;       // J*V
  std::vector<double> weights;    // V*J
  std::vector<int> parents;       // J
};

inline std::vector<int> ref_smpl_parents() {
  return {-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21};
}

inline std::vector<int> ref_smplx_parents() {
  std::vector<int> p = ref_smpl_parents();
  p.resize(22);
  p.push_back(15);  // jaw
  p.push_back(15);  // left eye
  p.push_back(15);  // right eye
  for (int side = 0; side < 2; ++side) {
    const int wrist = 20 + side;
    for (int finger = 0; finger < 5; ++finger) {
      const int base = int(p.size());
      p.push_back(wrist);
      p.push_back(base);
      p.push_back(base + 1);
    }
  }
  return p;  // 55
}

struct RandomSpec {
  int J = 24;
  int V = 60;
  int S = 10;
  bool float32 = false;
  char face_kind = 'i';
  int face_itemsize = 4;
  bool kintree_uint32_root = false;  // kintree_table as uint32 with 4294967295 at [0,0]
  bool posedirs_flat = false;        // (P, 3V) instead of (V, 3, P)
};

inline double round_as(bool f32, double v) {
  return f32 ? double(float(v)) : v;
}

// Builds the arrays of a random model and fills `ref` with exactly the stored values.
inline std::map<std::string, NpyArray> random_model(const RandomSpec& sp, uint32_t seed,
                                                    RefModel& ref) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::uniform_real_distribution<double> U01(0.0, 1.0);
  ref = RefModel{};
  ref.V = sp.V;
  ref.J = sp.J;
  ref.S = sp.S;
  ref.parents = sp.J == 24 ? ref_smpl_parents() : ref_smplx_parents();
  if (sp.J == 52) {  // SMPL+H: 22 body joints, then 15 + 15 hand joints
    ref.parents = ref_smpl_parents();
    ref.parents.resize(22);
    for (int side = 0; side < 2; ++side)
      for (int finger = 0; finger < 5; ++finger) {
        const int base = int(ref.parents.size());
        ref.parents.push_back(20 + side);
        ref.parents.push_back(base);
        ref.parents.push_back(base + 1);
      }
  }
  const int V = sp.V, J = sp.J, S = sp.S, P = 9 * (J - 1);
  auto r = [&](double v) { return round_as(sp.float32, v); };
  ref.vt.resize(size_t(V) * 3);
  for (auto& x : ref.vt) x = r(0.8 * U(rng));
  ref.F = 2 * V;
  ref.faces.resize(size_t(ref.F) * 3);
  for (int f = 0; f < ref.F; ++f) {
    ref.faces[size_t(f) * 3 + 0] = f % V;
    ref.faces[size_t(f) * 3 + 1] = (f * 7 + 1) % V;
    ref.faces[size_t(f) * 3 + 2] = (f * 13 + 5) % V;
  }
  ref.shapedirs.resize(size_t(V) * 3 * S);
  for (auto& x : ref.shapedirs) x = r(0.05 * U(rng));
  ref.posedirs.resize(size_t(V) * 3 * P);
  for (auto& x : ref.posedirs) x = r(0.01 * U(rng));
  ref.jreg.assign(size_t(J) * V, 0.0);
  for (int j = 0; j < J; ++j) {
    double s = 0;
    std::vector<double> row(size_t(V), 0.0);
    for (int k = 0; k < 5; ++k) {
      const int v = int(U01(rng) * V) % V;
      row[size_t(v)] += 0.1 + U01(rng);
    }
    for (double x : row) s += x;
    for (int v = 0; v < V; ++v) ref.jreg[size_t(j) * V + v] = r(row[size_t(v)] / s);
  }
  ref.weights.assign(size_t(V) * J, 0.0);
  for (int v = 0; v < V; ++v) {
    std::vector<double> row(size_t(J), 0.0);
    double s = 0;
    for (int k = 0; k < 4; ++k) row[size_t(int(U01(rng) * J) % J)] += 0.1 + U01(rng);
    for (double x : row) s += x;
    for (int j = 0; j < J; ++j) ref.weights[size_t(v) * J + j] = r(row[size_t(j)] / s);
  }

  std::map<std::string, NpyArray> a;
  a["v_template"] = NpyArray::from_doubles({V, 3}, ref.vt.data(), sp.float32);
  std::vector<int64_t> fi(ref.faces.begin(), ref.faces.end());
  a["f"] = NpyArray::from_ints({ref.F, 3}, fi.data(), sp.face_kind, sp.face_itemsize);
  a["shapedirs"] = NpyArray::from_doubles({V, 3, S}, ref.shapedirs.data(), sp.float32);
  if (sp.posedirs_flat) {
    std::vector<double> flat(size_t(P) * 3 * V);  // (P, 3V): flat[p][3v+k] = posedirs[v][k][p]
    for (int v = 0; v < V; ++v)
      for (int k = 0; k < 3; ++k)
        for (int p = 0; p < P; ++p)
          flat[size_t(p) * 3 * V + 3 * v + k] = ref.posedirs[(size_t(v) * 3 + k) * P + p];
    a["posedirs"] = NpyArray::from_doubles({P, 3 * V}, flat.data(), sp.float32);
  } else {
    a["posedirs"] = NpyArray::from_doubles({V, 3, P}, ref.posedirs.data(), sp.float32);
  }
  a["J_regressor"] = NpyArray::from_doubles({J, V}, ref.jreg.data(), sp.float32);
  a["weights"] = NpyArray::from_doubles({V, J}, ref.weights.data(), sp.float32);
  std::vector<int64_t> kt(size_t(2) * J);
  for (int j = 0; j < J; ++j) {
    kt[size_t(j)] = ref.parents[size_t(j)];
    kt[size_t(J + j)] = j;
  }
  if (sp.kintree_uint32_root) {
    kt[0] = 4294967295LL;
    a["kintree_table"] = NpyArray::from_ints({2, J}, kt.data(), 'u', 4);
  } else {
    a["kintree_table"] = NpyArray::from_ints({2, J}, kt.data(), 'i', 8);
  }
  return a;
}

// Rodrigues, written out: R = cos(t) I + sin(t) [k]x + (1 - cos(t)) k k^T.
inline void ref_rodrigues(const double* r, double R[9]) {
  const double t = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
  if (t < 1e-12) {
    const double I[9] = {1, -r[2], r[1], r[2], 1, -r[0], -r[1], r[0], 1};
    for (int i = 0; i < 9; ++i) R[i] = I[i];
    return;
  }
  const double k[3] = {r[0] / t, r[1] / t, r[2] / t};
  const double c = std::cos(t), s = std::sin(t), C = 1 - c;
  R[0] = c + k[0] * k[0] * C;
  R[1] = k[0] * k[1] * C - k[2] * s;
  R[2] = k[0] * k[2] * C + k[1] * s;
  R[3] = k[1] * k[0] * C + k[2] * s;
  R[4] = c + k[1] * k[1] * C;
  R[5] = k[1] * k[2] * C - k[0] * s;
  R[6] = k[2] * k[0] * C - k[1] * s;
  R[7] = k[2] * k[1] * C + k[0] * s;
  R[8] = c + k[2] * k[2] * C;
}

// coeffs: S shape (+ expression) coefficients; pose: J*3 axis-angles in joint order.
// Returns posed vertices (V*3) and posed joints (J*3).
inline void ref_forward(const RefModel& m, const std::vector<double>& coeffs,
                        const std::vector<double>& pose, const double transl[3],
                        std::vector<double>& verts, std::vector<double>& joints) {
  const int V = m.V, J = m.J, S = m.S, P = 9 * (J - 1);
  std::vector<double> vs(size_t(V) * 3);
  for (int v = 0; v < V; ++v)
    for (int k = 0; k < 3; ++k) {
      double x = m.vt[size_t(v) * 3 + k];
      for (int s = 0; s < S; ++s) x += m.shapedirs[(size_t(v) * 3 + k) * S + s] * coeffs[size_t(s)];
      vs[size_t(v) * 3 + k] = x;
    }
  std::vector<double> Jr(size_t(J) * 3, 0.0);
  for (int j = 0; j < J; ++j)
    for (int k = 0; k < 3; ++k)
      for (int v = 0; v < V; ++v)
        Jr[size_t(j) * 3 + k] += m.jreg[size_t(j) * V + v] * vs[size_t(v) * 3 + k];
  std::vector<double> R(size_t(J) * 9);
  for (int j = 0; j < J; ++j) ref_rodrigues(&pose[size_t(j) * 3], &R[size_t(j) * 9]);
  std::vector<double> feat(static_cast<size_t>(P));
  for (int j = 1; j < J; ++j)
    for (int q = 0; q < 9; ++q)
      feat[size_t(j - 1) * 9 + q] =
          R[size_t(j) * 9 + q] - ((q == 0 || q == 4 || q == 8) ? 1.0 : 0.0);
  std::vector<double> vp = vs;
  for (int v = 0; v < V; ++v)
    for (int k = 0; k < 3; ++k)
      for (int p = 0; p < P; ++p)
        vp[size_t(v) * 3 + k] += m.posedirs[(size_t(v) * 3 + k) * P + p] * feat[size_t(p)];
  // Global transforms as 3x4 [R | t].
  std::vector<double> G(size_t(J) * 12);
  for (int j = 0; j < J; ++j) {
    double L[12];
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) L[r * 4 + c] = R[size_t(j) * 9 + r * 3 + c];
      const int p = m.parents[size_t(j)];
      L[r * 4 + 3] = Jr[size_t(j) * 3 + r] - (p >= 0 ? Jr[size_t(p) * 3 + r] : 0.0);
    }
    const int p = m.parents[size_t(j)];
    if (p < 0) {
      for (int q = 0; q < 12; ++q) G[size_t(j) * 12 + q] = L[q];
    } else {
      const double* A = &G[size_t(p) * 12];
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 4; ++c) {
          double x = 0;
          for (int q = 0; q < 3; ++q) x += A[r * 4 + q] * L[q * 4 + c];
          if (c == 3) x += A[r * 4 + 3];
          G[size_t(j) * 12 + r * 4 + c] = x;
        }
      }
    }
  }
  joints.assign(size_t(J) * 3, 0.0);
  for (int j = 0; j < J; ++j)
    for (int r = 0; r < 3; ++r)
      joints[size_t(j) * 3 + r] = G[size_t(j) * 12 + r * 4 + 3] + transl[r];
  verts.assign(size_t(V) * 3, 0.0);
  for (int v = 0; v < V; ++v) {
    for (int j = 0; j < J; ++j) {
      const double w = m.weights[size_t(v) * J + j];
      if (w == 0) continue;
      const double* A = &G[size_t(j) * 12];
      // Rest -> posed: A * (x - J_j) + t_j.
      double d[3];
      for (int k = 0; k < 3; ++k) d[k] = vp[size_t(v) * 3 + k] - Jr[size_t(j) * 3 + k];
      for (int r = 0; r < 3; ++r)
        verts[size_t(v) * 3 + r] +=
            w * (A[r * 4 + 0] * d[0] + A[r * 4 + 1] * d[1] + A[r * 4 + 2] * d[2] + A[r * 4 + 3]);
    }
    for (int r = 0; r < 3; ++r) verts[size_t(v) * 3 + r] += transl[r];
  }
}

}  // namespace ks::testing
