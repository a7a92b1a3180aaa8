#include "meshrender/meshrender.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include "core/error.hpp"
#include "mesh/trimesh.hpp"

namespace ks {

namespace {

constexpr int kMaxSupersample = 8;

// A screen-space triangle ready for rasterisation (a whole face, or a piece of a face clipped
// by the near plane). Edge k is opposite corner k; w_k(p) = A[k] * px + B[k] * py + C[k] is
// >= 0 inside and equals |2 * area| * (screen barycentric of corner k).
struct RasterTri {
  double A[3], B[3], C[3];
  double inv_area2;  // 1 / |2 * area|
  float iz[3];       // 1 / z of the corners
  bool tie[3];       // whether a sample exactly on edge k belongs to this triangle
  bool clipped;      // corner barycentrics differ from the identity
  int face;
  int x0, y0, x1, y1;  // inclusive sample-index bounding box
  float bary[3][3];    // bary[k] = barycentrics of corner k in the original face
};

struct ClipVert {
  Eigen::Vector3d p;  // camera space
  Eigen::Vector3d b;  // barycentrics in the original face
};

// Sets up one screen triangle from its corners' sample-space coordinates and 1 / z. Returns
// false if it is degenerate, culled, or covers no sample.
bool setup_triangle(const double* sx, const double* sy, const float* iz, int face, int samples_w,
                    int samples_h, bool cull, RasterTri& t) {
  const double area2 = (sx[1] - sx[0]) * (sy[2] - sy[0]) - (sy[1] - sy[0]) * (sx[2] - sx[0]);
  if (!(std::abs(area2) > 1e-12)) return false;
  // Front-facing (normal towards the camera) <=> negative signed area with y pointing down.
  if (cull && area2 > 0) return false;
  const double minx = std::min({sx[0], sx[1], sx[2]}), maxx = std::max({sx[0], sx[1], sx[2]});
  const double miny = std::min({sy[0], sy[1], sy[2]}), maxy = std::max({sy[0], sy[1], sy[2]});
  const double lim = 1e9;
  t.x0 = int(std::max(0.0, std::ceil(std::max(minx, -lim) - 0.5)));
  t.x1 = int(std::min(double(samples_w - 1), std::floor(std::min(maxx, lim) - 0.5)));
  t.y0 = int(std::max(0.0, std::ceil(std::max(miny, -lim) - 0.5)));
  t.y1 = int(std::min(double(samples_h - 1), std::floor(std::min(maxy, lim) - 0.5)));
  if (t.x0 > t.x1 || t.y0 > t.y1) return false;
  const double orient = area2 > 0 ? 1.0 : -1.0;
  for (int k = 0; k < 3; ++k) {
    const int a = (k + 1) % 3, b = (k + 2) % 3;
    // Canonical edge direction (lexicographically smaller endpoint first) so that the two
    // triangles sharing an edge evaluate exactly opposite edge functions.
    const bool a_lo = sx[a] < sx[b] || (sx[a] == sx[b] && sy[a] < sy[b]);
    const int lo = a_lo ? a : b, hi = a_lo ? b : a;
    const double dx = sx[hi] - sx[lo], dy = sy[hi] - sy[lo];
    double A = -dy, B = dx, C = dy * sx[lo] - dx * sy[lo];
    // E_ab(p) = (b - a) x (p - a); E_ab(corner k) = area2.
    const double sg = (a_lo ? 1.0 : -1.0) * orient;
    A *= sg;
    B *= sg;
    C *= sg;
    t.A[k] = A;
    t.B[k] = B;
    t.C[k] = C;
    t.tie[k] = A > 0 || (A == 0 && B > 0);
    t.iz[k] = iz[k];
  }
  t.inv_area2 = 1.0 / std::abs(area2);
  t.face = face;
  t.clipped = false;
  return true;
}

// The same for a triangle given by camera-space corners (a piece of a clipped face).
bool setup_clipped(const ClipVert* cv, int face, const Camera& cam, double S, int samples_w,
                   int samples_h, bool cull, RasterTri& t) {
  double sx[3], sy[3];
  float iz[3];
  for (int k = 0; k < 3; ++k) {
    const double z = cv[k].p.z();
    sx[k] = S * (cam.fx * cv[k].p.x() / z + cam.cx);
    sy[k] = S * (cam.fy * cv[k].p.y() / z + cam.cy);
    iz[k] = float(1.0 / z);
  }
  if (!setup_triangle(sx, sy, iz, face, samples_w, samples_h, cull, t)) return false;
  t.clipped = true;
  for (int k = 0; k < 3; ++k)
    for (int m = 0; m < 3; ++m) t.bary[k][m] = float(cv[k].b[m]);
  return true;
}

// Clips a triangle against z >= near (Sutherland-Hodgman); returns the polygon size (0, 3, 4).
int clip_near(const ClipVert in[3], double near, ClipVert out[4]) {
  int n = 0;
  for (int k = 0; k < 3; ++k) {
    const ClipVert& a = in[k];
    const ClipVert& b = in[(k + 1) % 3];
    const bool ain = a.p.z() >= near, bin = b.p.z() >= near;
    if (ain) out[n++] = a;
    if (ain != bin) {
      const double s = (near - a.p.z()) / (b.p.z() - a.p.z());
      out[n].p = a.p + s * (b.p - a.p);
      out[n].p.z() = near;
      out[n].b = a.b + s * (b.b - a.b);
      ++n;
    }
  }
  return n;
}

inline void sample_texture(const Image& tex, double u, double v, float* rgb) {
  const double x = u * tex.width - 0.5, y = (1.0 - v) * tex.height - 0.5;
  const int x0 = int(std::floor(x)), y0 = int(std::floor(y));
  const float fx = float(x - x0), fy = float(y - y0);
  auto cl = [](int a, int n) { return a < 0 ? 0 : (a >= n ? n - 1 : a); };
  const int xa = cl(x0, tex.width), xb = cl(x0 + 1, tex.width);
  const int ya = cl(y0, tex.height), yb = cl(y0 + 1, tex.height);
  const int c = tex.channels;
  for (int k = 0; k < 3; ++k) {
    const int kk = c >= 3 ? k : 0;
    const float v00 = tex.at(xa, ya, kk), v10 = tex.at(xb, ya, kk);
    const float v01 = tex.at(xa, yb, kk), v11 = tex.at(xb, yb, kk);
    rgb[k] = (1 - fy) * ((1 - fx) * v00 + fx * v10) + fy * ((1 - fx) * v01 + fx * v11);
  }
}

void check_input(const Camera& cam, const MeshRenderInput& in, const MeshRenderOptions& opt) {
  if (cam.width <= 0 || cam.height <= 0) throw Error("render_mesh: camera size must be positive");
  if (!(cam.fx > 0) || !(cam.fy > 0)) throw Error("render_mesh: focal lengths must be positive");
  if (opt.supersample < 1 || opt.supersample > kMaxSupersample)
    throw Error("render_mesh: supersample must be in 1.." + std::to_string(kMaxSupersample));
  if (opt.tile_size < 1) throw Error("render_mesh: tile_size must be positive");
  if (!(opt.near > 0)) throw Error("render_mesh: near plane must be positive");
  if (!in.vertices || !in.faces) throw Error("render_mesh: vertices and faces are required");
  const auto& V = *in.vertices;
  const auto& F = *in.faces;
  const long N = V.rows();
  if (V.cols() != 3) throw Error("render_mesh: vertices must be N x 3");
  if (F.cols() != 3 && F.rows() > 0) throw Error("render_mesh: faces must be M x 3");
  if (F.size() > 0 && (F.minCoeff() < 0 || F.maxCoeff() >= N))
    throw Error("render_mesh: face index out of range");
  if (in.colors && (in.colors->rows() != N || in.colors->cols() != 3))
    throw Error("render_mesh: colors must be N x 3 (one row per vertex)");
  if (in.normals && (in.normals->rows() != N || in.normals->cols() != 3))
    throw Error("render_mesh: normals must be N x 3 (one row per vertex)");
  if (in.labels && long(in.labels->size()) != N)
    throw Error("render_mesh: labels must have one entry per vertex");
  if (in.texture) {
    if (in.texture->empty() || in.texture->channels < 1) throw Error("render_mesh: empty texture");
    if (!in.uvs || in.uvs->cols() != 2) throw Error("render_mesh: a texture needs T x 2 uvs");
    const Eigen::MatrixXi& UF = in.uv_faces ? *in.uv_faces : F;
    if (UF.rows() != F.rows() || (UF.size() > 0 && UF.cols() != 3))
      throw Error("render_mesh: uv_faces must be M x 3");
    if (UF.size() > 0 && (UF.minCoeff() < 0 || UF.maxCoeff() >= in.uvs->rows()))
      throw Error("render_mesh: uv index out of range");
  }
}

}  // namespace

MeshRenderOutput render_mesh(const Camera& cam, const MeshRenderInput& in,
                             const MeshRenderOptions& opt) {
  check_input(cam, in, opt);
  const Eigen::MatrixXd& V = *in.vertices;
  const Eigen::MatrixXi& F = *in.faces;
  const int W = cam.width, H = cam.height, S = opt.supersample;
  const int SW = W * S, SH = H * S;
  const long N = V.rows();
  const long M = F.rows();

  // Per-vertex camera-space positions and attributes (float, structure of arrays).
  std::vector<Eigen::Vector3d> pc(N);
#pragma omp parallel for schedule(static)
  for (long i = 0; i < N; ++i) pc[i] = cam.R * V.row(i).transpose() + cam.t;

  const bool need_normals = opt.want_normal || (opt.lighting && opt.want_rgb);
  std::vector<float> ncam;
  if (need_normals) {
    Eigen::MatrixXd Nw;
    const Eigen::MatrixXd* Np = in.normals;
    if (!Np) {
      Nw = vertex_normals(V, F);
      Np = &Nw;
    }
    ncam.resize(size_t(N) * 3);
    for (long i = 0; i < N; ++i) {
      const Eigen::Vector3d n = cam.R * Np->row(i).transpose();
      for (int k = 0; k < 3; ++k) ncam[size_t(i) * 3 + k] = float(n[k]);
    }
  }
  std::vector<float> col;
  const bool use_texture = in.texture != nullptr;
  if (opt.want_rgb && !use_texture && in.colors) {
    col.resize(size_t(N) * 3);
    for (long i = 0; i < N; ++i)
      for (int k = 0; k < 3; ++k) col[size_t(i) * 3 + k] = float((*in.colors)(i, k));
  }
  const Eigen::MatrixXi& UF = (use_texture && in.uv_faces) ? *in.uv_faces : F;

  // Per-vertex sample-space projection (vertices in front of the near plane).
  std::vector<double> vsx(static_cast<size_t>(N)), vsy(static_cast<size_t>(N));
  std::vector<float> viz(static_cast<size_t>(N));
#pragma omp parallel for schedule(static)
  for (long i = 0; i < N; ++i) {
    const double z = pc[i].z();
    if (z >= opt.near) {
      vsx[i] = S * (cam.fx * pc[i].x() / z + cam.cx);
      vsy[i] = S * (cam.fy * pc[i].y() / z + cam.cy);
      viz[i] = float(1.0 / z);
    } else {
      viz[i] = 0.0f;
    }
  }

  // Per-face sample bounding boxes (parallel); faces crossing the near plane are clipped
  // serially into separate raster triangles. Triangle ids: face f -> f, clipped piece k -> M + k.
  struct Box {
    int x0, y0, x1, y1;
  };
  std::vector<Box> boxes(static_cast<size_t>(M));
  std::vector<char> needs_clip(static_cast<size_t>(M), 0);
#pragma omp parallel for schedule(static)
  for (long f = 0; f < M; ++f) {
    Box& bx = boxes[size_t(f)];
    bx = {1, 1, 0, 0};  // empty
    int nin = 0;
    for (int k = 0; k < 3; ++k) nin += pc[F(f, k)].z() >= opt.near;
    if (nin == 0) continue;
    if (nin < 3) {
      needs_clip[size_t(f)] = 1;
      continue;
    }
    double sx[3], sy[3];
    float iz[3];
    for (int k = 0; k < 3; ++k) {
      sx[k] = vsx[F(f, k)];
      sy[k] = vsy[F(f, k)];
      iz[k] = viz[F(f, k)];
    }
    RasterTri t;
    if (setup_triangle(sx, sy, iz, int(f), SW, SH, opt.cull_backfaces, t))
      bx = {t.x0, t.y0, t.x1, t.y1};
  }
  std::vector<RasterTri> clipped;
  {
    const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
    for (long f = 0; f < M; ++f) {
      if (!needs_clip[size_t(f)]) continue;
      ClipVert cv[3];
      for (int k = 0; k < 3; ++k) {
        cv[k].p = pc[F(f, k)];
        cv[k].b = I.col(k);
      }
      ClipVert poly[4];
      const int n = clip_near(cv, opt.near, poly);
      for (int k = 1; k + 1 < n; ++k) {
        ClipVert tri[3] = {poly[0], poly[k], poly[k + 1]};
        RasterTri t;
        if (setup_clipped(tri, int(f), cam, S, SW, SH, opt.cull_backfaces, t)) clipped.push_back(t);
      }
    }
  }
  auto box_of = [&](long id) -> Box {
    if (id < M) return boxes[size_t(id)];
    const RasterTri& t = clipped[size_t(id - M)];
    return {t.x0, t.y0, t.x1, t.y1};
  };
  const long num_ids = M + long(clipped.size());

  // Binning into tiles (tile = T x T output pixels = T*S x T*S samples), in id order.
  const int T = opt.tile_size, TS = T * S;
  const int tiles_x = (W + T - 1) / T, tiles_y = (H + T - 1) / T;
  const int num_tiles = tiles_x * tiles_y;
  std::vector<int> tile_start(size_t(num_tiles) + 1, 0);
  for (long id = 0; id < num_ids; ++id) {
    const Box bx = box_of(id);
    if (bx.x0 > bx.x1) continue;
    for (int ty = bx.y0 / TS; ty <= bx.y1 / TS; ++ty)
      for (int tx = bx.x0 / TS; tx <= bx.x1 / TS; ++tx) ++tile_start[size_t(ty * tiles_x + tx) + 1];
  }
  for (int i = 0; i < num_tiles; ++i) tile_start[i + 1] += tile_start[i];
  std::vector<int> tile_tris(size_t(tile_start[num_tiles]));
  {
    std::vector<int> fill(tile_start.begin(), tile_start.end() - 1);
    for (long id = 0; id < num_ids; ++id) {
      const Box bx = box_of(id);
      if (bx.x0 > bx.x1) continue;
      for (int ty = bx.y0 / TS; ty <= bx.y1 / TS; ++ty)
        for (int tx = bx.x0 / TS; tx <= bx.x1 / TS; ++tx)
          tile_tris[size_t(fill[size_t(ty * tiles_x + tx)]++)] = int(id);
    }
  }

  MeshRenderOutput out;
  out.width = W;
  out.height = H;
  if (opt.want_rgb) out.rgb = Image(W, H, 3);
  if (opt.want_mask) out.mask = Image(W, H, 1);
  if (opt.want_depth) out.depth = Image(W, H, 1);
  if (opt.want_normal) out.normal = Image(W, H, 3);
  if (opt.want_labels) out.labels.assign(size_t(W) * H, -1);

  const Eigen::Vector3f bg = opt.background.cast<float>();
  const Eigen::Vector3f light = opt.light_dir.normalized().cast<float>();
  const float ambient = float(opt.ambient);
  const float inv_ss = 1.0f / float(S * S);

#pragma omp parallel
  {
    // Per-thread tile buffers, allocated once.
    std::vector<float> zbuf(size_t(TS) * TS);
    std::vector<int> tbuf(size_t(TS) * TS);
    std::vector<float> l1buf(size_t(TS) * TS), l2buf(size_t(TS) * TS);
    std::array<int, kMaxSupersample * kMaxSupersample> slabels{};

#pragma omp for schedule(dynamic, 1)
    for (int tile = 0; tile < num_tiles; ++tile) {
      const int tx = tile % tiles_x, ty = tile / tiles_x;
      const int sx0 = tx * TS, sy0 = ty * TS;
      const int sx1 = std::min(sx0 + TS, SW) - 1, sy1 = std::min(sy0 + TS, SH) - 1;
      std::fill(zbuf.begin(), zbuf.end(), 0.0f);  // stores 1/z: larger is nearer
      std::fill(tbuf.begin(), tbuf.end(), -1);

      for (int q = tile_start[tile]; q < tile_start[tile + 1]; ++q) {
        const int ti = tile_tris[q];
        RasterTri local;
        const RasterTri* tp;
        if (ti < M) {
          double sx[3], sy[3];
          float iz[3];
          for (int k = 0; k < 3; ++k) {
            sx[k] = vsx[F(ti, k)];
            sy[k] = vsy[F(ti, k)];
            iz[k] = viz[F(ti, k)];
          }
          setup_triangle(sx, sy, iz, ti, SW, SH, opt.cull_backfaces, local);
          tp = &local;
        } else {
          tp = &clipped[size_t(ti - M)];
        }
        const RasterTri& t = *tp;
        const int ix0 = std::max(t.x0, sx0), ix1 = std::min(t.x1, sx1);
        const int iy0 = std::max(t.y0, sy0), iy1 = std::min(t.y1, sy1);
        for (int j = iy0; j <= iy1; ++j) {
          const double py = j + 0.5;
          for (int i = ix0; i <= ix1; ++i) {
            const double px = i + 0.5;
            const double w0 = t.A[0] * px + t.B[0] * py + t.C[0];
            const double w1 = t.A[1] * px + t.B[1] * py + t.C[1];
            const double w2 = t.A[2] * px + t.B[2] * py + t.C[2];
            if (w0 < 0 || w1 < 0 || w2 < 0) continue;
            if ((w0 == 0 && !t.tie[0]) || (w1 == 0 && !t.tie[1]) || (w2 == 0 && !t.tie[2]))
              continue;
            const float l1 = float(w1 * t.inv_area2), l2 = float(w2 * t.inv_area2);
            const float l0 = 1.0f - l1 - l2;
            const float iz = l0 * t.iz[0] + l1 * t.iz[1] + l2 * t.iz[2];
            const size_t s = size_t(j - sy0) * TS + (i - sx0);
            if (iz > zbuf[s]) {
              zbuf[s] = iz;
              tbuf[s] = ti;
              l1buf[s] = l1;
              l2buf[s] = l2;
            }
          }
        }
      }

      // Resolve the tile's pixels.
      const int px0 = tx * T, py0 = ty * T;
      const int px1 = std::min(px0 + T, W), py1 = std::min(py0 + T, H);
      for (int y = py0; y < py1; ++y) {
        for (int x = px0; x < px1; ++x) {
          Eigen::Vector3f rgb_sum = Eigen::Vector3f::Zero();
          Eigen::Vector3f n_sum = Eigen::Vector3f::Zero();
          int covered = 0;
          float zmin = std::numeric_limits<float>::infinity();
          int nl = 0;
          for (int sj = 0; sj < S; ++sj) {
            for (int si = 0; si < S; ++si) {
              const size_t s = size_t(y * S + sj - sy0) * TS + (x * S + si - sx0);
              const int ti = tbuf[s];
              if (ti < 0) {
                rgb_sum += bg;
                slabels[nl++] = -1;
                continue;
              }
              ++covered;
              const bool is_face = ti < M;
              const RasterTri* ct = is_face ? nullptr : &clipped[size_t(ti - M)];
              const int f = is_face ? ti : ct->face;
              const int v0 = F(f, 0), v1 = F(f, 1), v2 = F(f, 2);
              const float l1 = l1buf[s], l2 = l2buf[s], l0 = 1.0f - l1 - l2;
              float q0, q1, q2;
              if (is_face) {
                q0 = l0 * viz[v0];
                q1 = l1 * viz[v1];
                q2 = l2 * viz[v2];
              } else {
                q0 = l0 * ct->iz[0];
                q1 = l1 * ct->iz[1];
                q2 = l2 * ct->iz[2];
              }
              const float iz = q0 + q1 + q2;
              const float z = 1.0f / iz;
              zmin = std::min(zmin, z);
              q0 /= iz;
              q1 /= iz;
              q2 /= iz;
              float b[3] = {q0, q1, q2};
              if (!is_face) {
                for (int m = 0; m < 3; ++m)
                  b[m] = q0 * ct->bary[0][m] + q1 * ct->bary[1][m] + q2 * ct->bary[2][m];
              }
              Eigen::Vector3f n = Eigen::Vector3f::Zero();
              if (need_normals) {
                for (int k = 0; k < 3; ++k)
                  n[k] = b[0] * ncam[size_t(v0) * 3 + k] + b[1] * ncam[size_t(v1) * 3 + k] +
                         b[2] * ncam[size_t(v2) * 3 + k];
                const float len = n.norm();
                if (len > 0) n /= len;
                n_sum += n;
              }
              if (opt.want_rgb) {
                float c[3] = {0.7f, 0.7f, 0.7f};
                if (use_texture) {
                  const auto& uv = *in.uvs;
                  const int u0 = UF(f, 0), u1 = UF(f, 1), u2 = UF(f, 2);
                  const double u = b[0] * uv(u0, 0) + b[1] * uv(u1, 0) + b[2] * uv(u2, 0);
                  const double v = b[0] * uv(u0, 1) + b[1] * uv(u1, 1) + b[2] * uv(u2, 1);
                  sample_texture(*in.texture, u, v, c);
                } else if (!col.empty()) {
                  for (int k = 0; k < 3; ++k)
                    c[k] = b[0] * col[size_t(v0) * 3 + k] + b[1] * col[size_t(v1) * 3 + k] +
                           b[2] * col[size_t(v2) * 3 + k];
                }
                if (opt.lighting) {
                  // The sample's camera-space position is along the ray; shade the side that
                  // faces the camera.
                  const float rx = (float((x * S + si + 0.5f) / S) - float(cam.cx)) / float(cam.fx);
                  const float ry = (float((y * S + sj + 0.5f) / S) - float(cam.cy)) / float(cam.fy);
                  Eigen::Vector3f ns = n;
                  if (ns.x() * rx + ns.y() * ry + ns.z() > 0) ns = -ns;
                  const float shade = ambient + (1.0f - ambient) * std::max(0.0f, ns.dot(light));
                  for (int k = 0; k < 3; ++k) c[k] *= shade;
                }
                rgb_sum += Eigen::Vector3f(c[0], c[1], c[2]);
              }
              if (opt.want_labels) {
                int label = -1;
                if (in.labels) {
                  const int vm = b[0] >= b[1] ? (b[0] >= b[2] ? v0 : v2) : (b[1] >= b[2] ? v1 : v2);
                  label = (*in.labels)[vm];
                }
                slabels[nl++] = label;
              }
            }
          }
          if (opt.want_rgb)
            for (int k = 0; k < 3; ++k) out.rgb.at(x, y, k) = rgb_sum[k] * inv_ss;
          if (opt.want_mask) out.mask.at(x, y, 0) = covered * inv_ss;
          if (covered > 0) {
            if (opt.want_depth) out.depth.at(x, y, 0) = zmin;
            if (opt.want_normal) {
              const float len = n_sum.norm();
              if (len > 0)
                for (int k = 0; k < 3; ++k) out.normal.at(x, y, k) = n_sum[k] / len;
            }
          }
          if (opt.want_labels) {
            int best = -1, best_count = 0;
            for (int a = 0; a < nl; ++a) {
              int c = 0;
              for (int bb = 0; bb < nl; ++bb) c += slabels[bb] == slabels[a];
              if (c > best_count || (c == best_count && slabels[a] >= 0 && best < 0)) {
                best = slabels[a];
                best_count = c;
              }
            }
            out.labels[size_t(y) * W + x] = best;
          }
        }
      }
    }
  }
  return out;
}

Image normal_to_rgb(const Image& normal, const Eigen::Vector3d& background) {
  Image out(normal.width, normal.height, 3);
  for (int y = 0; y < normal.height; ++y)
    for (int x = 0; x < normal.width; ++x) {
      const float nx = normal.at(x, y, 0), ny = normal.at(x, y, 1), nz = normal.at(x, y, 2);
      if (nx == 0 && ny == 0 && nz == 0) {
        for (int k = 0; k < 3; ++k) out.at(x, y, k) = float(background[k]);
      } else {
        out.at(x, y, 0) = 0.5f + 0.5f * nx;
        out.at(x, y, 1) = 0.5f - 0.5f * ny;
        out.at(x, y, 2) = 0.5f - 0.5f * nz;
      }
    }
  return out;
}

Image labels_to_rgb(const std::vector<int>& labels, int width, int height,
                    const Eigen::Vector3d& background) {
  if (long(labels.size()) != long(width) * height)
    throw Error("labels_to_rgb: label map size does not match width x height");
  // A fixed palette of well separated colours (cycled for labels beyond its length).
  static const float palette[][3] = {
      {0.90f, 0.10f, 0.10f}, {0.10f, 0.60f, 0.90f}, {0.95f, 0.75f, 0.10f}, {0.20f, 0.75f, 0.25f},
      {0.60f, 0.30f, 0.85f}, {0.95f, 0.45f, 0.10f}, {0.10f, 0.80f, 0.75f}, {0.85f, 0.35f, 0.60f},
      {0.50f, 0.50f, 0.10f}, {0.20f, 0.30f, 0.70f}, {0.60f, 0.85f, 0.40f}, {0.55f, 0.20f, 0.20f},
      {0.30f, 0.55f, 0.55f}, {0.95f, 0.60f, 0.70f}, {0.40f, 0.25f, 0.10f}, {0.70f, 0.70f, 0.95f}};
  constexpr int np = int(sizeof(palette) / sizeof(palette[0]));
  Image out(width, height, 3);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const int l = labels[size_t(y) * width + x];
      for (int k = 0; k < 3; ++k)
        out.at(x, y, k) = l < 0 ? float(background[k]) : palette[l % np][k];
    }
  return out;
}

MeshRenderOutput render_depth(const Eigen::MatrixXd& V, const Eigen::MatrixXi& F, const Camera& cam,
                              const std::vector<int>* labels) {
  MeshRenderInput ri;
  ri.vertices = &V;
  ri.faces = &F;
  ri.labels = labels;
  MeshRenderOptions ro;
  ro.want_rgb = false;
  ro.want_depth = true;
  ro.want_labels = labels != nullptr;
  ro.cull_backfaces = true;
  return render_mesh(cam, ri, ro);
}

}  // namespace ks
