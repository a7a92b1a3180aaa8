// glTF export (src/gltf/): the GLB round trip through the reader, the skin's algebra against
// kinesplat's own posing, and malformed GLB files.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <functional>

#include "../avatar/tiny_avatar.hpp"
#include "../cli_run.hpp"
#include "../temp_dir.hpp"
#include "avatar/pose.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "core/rotation.hpp"
#include "gltf/glb.hpp"
#include "gltf/gltf_export.hpp"
#include "mesh/trimesh.hpp"
#include "motion/amass.hpp"
#include "raster/sh.hpp"

namespace ks {
namespace {

namespace fs = std::filesystem;

int attr(const nlohmann::json& prim, const std::string& name) {
  return prim.at("attributes").at(name).get<int>();
}

// A node's local matrix at frame f of animation `anim` (-1: the node's rest transform).
Eigen::Matrix4d node_local(const GlbDocument& d, int node, int anim, int f) {
  const auto& n = d.gltf["nodes"][size_t(node)];
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  if (n.contains("translation"))
    t = Eigen::Vector3d(n["translation"][0], n["translation"][1], n["translation"][2]);
  if (n.contains("rotation"))
    q = Eigen::Quaterniond(n["rotation"][3], n["rotation"][0], n["rotation"][1], n["rotation"][2]);
  if (anim >= 0) {
    const auto& a = d.gltf["animations"][size_t(anim)];
    for (const auto& ch : a["channels"]) {
      if (ch["target"]["node"] != node) continue;
      const auto out = d.read_floats(a["samplers"][size_t(ch["sampler"].get<int>())]["output"]);
      if (ch["target"]["path"] == "rotation")
        q = Eigen::Quaterniond(out[4 * size_t(f) + 3], out[4 * size_t(f)], out[4 * size_t(f) + 1],
                               out[4 * size_t(f) + 2]);
      else
        t = Eigen::Vector3d(out[3 * size_t(f)], out[3 * size_t(f) + 1], out[3 * size_t(f) + 2]);
    }
  }
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = q.normalized().toRotationMatrix();
  m.topRightCorner<3, 1>() = t;
  return m;
}

// glTF's joint matrices (global transform x inverse bind matrix) of skin 0 at a frame.
std::vector<Eigen::Matrix4d> joint_matrices(const GlbDocument& d, int anim, int f) {
  const int nn = int(d.gltf["nodes"].size());
  std::vector<int> parent(size_t(nn), -1);
  for (int i = 0; i < nn; ++i)
    for (const auto& c : d.gltf["nodes"][size_t(i)].value("children", nlohmann::json::array()))
      parent[c.get<size_t>()] = i;
  std::vector<Eigen::Matrix4d> global(static_cast<size_t>(nn));
  std::vector<bool> done(size_t(nn), false);
  std::function<Eigen::Matrix4d(int)> world = [&](int i) -> Eigen::Matrix4d {
    if (!done[size_t(i)]) {
      global[size_t(i)] = (parent[size_t(i)] >= 0 ? world(parent[size_t(i)])
                                                  : Eigen::Matrix4d(Eigen::Matrix4d::Identity())) *
                          node_local(d, i, anim, f);
      done[size_t(i)] = true;
    }
    return global[size_t(i)];
  };
  const auto& skin = d.gltf["skins"][0];
  const auto ibm = d.read_floats(skin["inverseBindMatrices"]);
  std::vector<Eigen::Matrix4d> out;
  for (size_t j = 0; j < skin["joints"].size(); ++j) {
    Eigen::Matrix4d inv;
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) inv(r, c) = ibm[16 * j + size_t(4 * c + r)];
    out.push_back(world(skin["joints"][j].get<int>()) * inv);
  }
  return out;
}

float sigmoidf(float x) {
  return 1.f / (1.f + std::exp(-x));
}

TEST(Gltf, RoundTripMeshSplatsSkinAndAnimation) {
  const Avatar a = test::tiny_avatar(1);
  const Motion walk = builtin_motion("walk", 6);
  const Motion wave = builtin_motion("wave", 4);
  GltfExportOptions vc;  // the template's own vertices with their colours: one glTF vertex each
  vc.vertex_colors = true;
  vc.template_surface = true;
  const std::vector<uint8_t> bytes = avatar_gltf(a, {walk, wave}, vc);
  const GlbDocument d = parse_glb(bytes, "mem.glb");
  const auto& g = d.gltf;
  EXPECT_EQ(g["asset"]["version"], "2.0");
  const int J = a.num_joints();
  for (int j = 0; j < J; ++j) EXPECT_EQ(g["nodes"][size_t(j)]["name"], a.joint_names[size_t(j)]);
  // Rest: the joint matrices are the identity (A_j of the rest pose).
  for (const auto& m : joint_matrices(d, -1, 0))
    EXPECT_LT((m - Eigen::Matrix4d::Identity()).norm(), 1e-6);
  // Inverse binds: translation by -rest_j.
  const auto ibm = d.read_floats(g["skins"][0]["inverseBindMatrices"]);
  for (int j = 0; j < J; ++j)
    for (int k = 0; k < 3; ++k)
      EXPECT_FLOAT_EQ(ibm[16 * size_t(j) + 12 + size_t(k)], float(-a.rest_joints(j, k)));

  // The mesh: positions, colours, weights as baked.
  ASSERT_EQ(g["meshes"].size(), 2u);
  const auto& mp = g["meshes"][0]["primitives"][0];
  EXPECT_EQ(mp["mode"], 4);
  const auto pos = d.read_floats(attr(mp, "POSITION"));
  ASSERT_EQ(pos.size(), size_t(3 * a.template_vertices.rows()));
  for (long v = 0; v < a.template_vertices.rows(); ++v)
    for (int k = 0; k < 3; ++k)
      EXPECT_FLOAT_EQ(pos[3 * size_t(v) + size_t(k)], float(a.template_vertices(v, k)));
  const auto idx = d.read_uints(mp["indices"]);
  ASSERT_EQ(idx.size(), size_t(3 * a.template_faces.rows()));
  for (long f = 0; f < a.template_faces.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      EXPECT_EQ(idx[3 * size_t(f) + size_t(k)], uint32_t(a.template_faces(f, k)));
  const BakedVertexAttributes baked = bake_vertex_attributes(a);
  const auto col = d.read_floats(attr(mp, "COLOR_0"));
  const auto mj = d.read_uints(attr(mp, "JOINTS_0"));
  const auto mw = d.read_floats(attr(mp, "WEIGHTS_0"));
  for (size_t v = 0; v < pos.size() / 3; ++v) {
    // Template vertex v carries Gaussian v (tiny_avatar anchors them there): its own colour.
    for (int k = 0; k < 3; ++k) {
      const float c = float(a.gaussians.sh[v * 12 + size_t(k)] * sh::kC0 + 0.5);
      EXPECT_NEAR(baked.srgb[3 * v + size_t(k)], c, 1e-6);
      EXPECT_NEAR(col[3 * v + size_t(k)], srgb_to_linear(c), 1e-6);
    }
    float sum = 0;
    for (int s = 0; s < 4; ++s) {
      sum += mw[4 * v + size_t(s)];
      if (mw[4 * v + size_t(s)] > 0) {
        EXPECT_EQ(int(mj[4 * v + size_t(s)]), baked.joints[4 * v + size_t(s)]);
      }
      // The same weight per joint as the Gaussian's own skin.
      double own = 0;
      for (int t = 0; t < 4; ++t)
        if (a.skin_joints[4 * v + size_t(t)] == baked.joints[4 * v + size_t(s)])
          own += a.skin_weights[4 * v + size_t(t)];
      if (mw[4 * v + size_t(s)] > 0) {
        EXPECT_NEAR(mw[4 * v + size_t(s)], own, 1e-6);
      }
    }
    EXPECT_NEAR(sum, 1.f, 1e-6);
  }

  // The splats: KHR_gaussian_splatting attributes, activated.
  const auto& sp = g["meshes"][1]["primitives"][0];
  EXPECT_EQ(sp["mode"], 0);
  EXPECT_EQ(sp["extensions"]["KHR_gaussian_splatting"]["kernel"], "ellipse");
  EXPECT_EQ(g["extensionsUsed"], nlohmann::json({"KHR_materials_unlit", "KHR_gaussian_splatting"}));
  const size_t N = a.gaussians.size();
  const auto spos = d.read_floats(attr(sp, "POSITION"));
  const auto rot = d.read_floats(attr(sp, "KHR_gaussian_splatting:ROTATION"));
  const auto scl = d.read_floats(attr(sp, "KHR_gaussian_splatting:SCALE"));
  const auto opa = d.read_floats(attr(sp, "KHR_gaussian_splatting:OPACITY"));
  const auto sj = d.read_uints(attr(sp, "JOINTS_0"));
  const auto sw = d.read_floats(attr(sp, "WEIGHTS_0"));
  ASSERT_EQ(spos.size(), 3 * N);
  for (size_t i = 0; i < N; ++i) {
    for (int k = 0; k < 3; ++k) {
      EXPECT_FLOAT_EQ(spos[3 * i + size_t(k)], a.gaussians.means[3 * i + size_t(k)]);
      EXPECT_NEAR(scl[3 * i + size_t(k)], std::exp(a.gaussians.log_scales[3 * i + size_t(k)]),
                  1e-7);
    }
    const float* q = &a.gaussians.quats[4 * i];
    const float qn = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    EXPECT_NEAR(rot[4 * i + 3], q[0] / qn, 1e-6);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(rot[4 * i + size_t(k)], q[k + 1] / qn, 1e-6);
    EXPECT_NEAR(opa[i], sigmoidf(a.gaussians.opacity_logits[i]), 1e-7);
    for (int s = 0; s < 4; ++s) {
      EXPECT_FLOAT_EQ(sw[4 * i + size_t(s)], a.skin_weights[4 * i + size_t(s)]);
      if (sw[4 * i + size_t(s)] > 0) {
        EXPECT_EQ(int(sj[4 * i + size_t(s)]), a.skin_joints[4 * i + size_t(s)]);
      }
    }
    // Slots of weight 0 name joint 0 (glTF's rule).
    for (int s = 0; s < 4; ++s)
      if (sw[4 * i + size_t(s)] == 0) {
        EXPECT_EQ(sj[4 * i + size_t(s)], 0u);
      }
  }
  const int K = a.gaussians.coeffs();
  for (int k = 0; k < K; ++k) {
    const int l = int(std::sqrt(double(k))), m = k - l * l;
    const auto c = d.read_floats(attr(sp, "KHR_gaussian_splatting:SH_DEGREE_" + std::to_string(l) +
                                              "_COEF_" + std::to_string(m)));
    for (size_t i = 0; i < N; ++i)
      for (int ch = 0; ch < 3; ++ch)
        EXPECT_FLOAT_EQ(c[3 * i + size_t(ch)],
                        a.gaussians.sh[(i * size_t(K) + size_t(k)) * 3 + size_t(ch)]);
  }

  // Animations: keyed at frame / fps, and at each frame the joint matrices are kinesplat's A_j.
  ASSERT_EQ(g["animations"].size(), 2u);
  const std::vector<const Motion*> motions = {&walk, &wave};
  for (size_t ai = 0; ai < 2; ++ai) {
    const Motion& mo = *motions[ai];
    const auto& an = g["animations"][ai];
    EXPECT_EQ(an["name"], mo.name);
    EXPECT_EQ(an["channels"].size(), size_t(J + 1));
    const auto times = d.read_floats(an["samplers"][0]["input"]);
    ASSERT_EQ(times.size(), mo.frames.size());
    for (size_t f = 0; f < times.size(); ++f) {
      EXPECT_NEAR(times[f], double(f) / mo.fps, 1e-6);
      const auto want = avatar_joint_transforms(a, mo.frames[f]);
      const auto got = joint_matrices(d, int(ai), int(f));
      for (int j = 0; j < J; ++j)
        EXPECT_LT((want[size_t(j)] - got[size_t(j)]).norm(), 1e-5) << f << " " << j;
      const Eigen::MatrixXd pose = avatar_full_pose(a, mo.frames[f]);
      for (int j = 0; j < J; ++j) {
        const auto out = d.read_floats(an["samplers"][size_t(j)]["output"]);
        const Eigen::Quaterniond q(out[4 * f + 3], out[4 * f], out[4 * f + 1], out[4 * f + 2]);
        const Eigen::Matrix3d R = axis_angle_to_matrix<double>(pose.row(j).transpose());
        EXPECT_LT((q.toRotationMatrix() - R).norm(), 1e-6);
      }
    }
  }
}

TEST(Gltf, MeshFollowsTheSplats) {
  // tiny_avatar: template vertex v carries Gaussian v, its centre offset from the vertex, its
  // opacity sigmoid(2) = 0.88, scales 0.05, 0.06, 0.07.
  const Avatar a = test::tiny_avatar();
  const Eigen::MatrixXd S = splat_surface(a, gaussians_per_vertex(a));
  const Eigen::MatrixXd n = vertex_normals(a.template_vertices, a.template_faces);
  const double r = 0.5 * (0.06 + 0.07) * std::sqrt(2 * std::log(2 * sigmoidf(2.f)));
  for (long v = 0; v < S.rows(); ++v) {
    const Eigen::Vector3d mean(a.gaussians.means[3 * size_t(v)],
                               a.gaussians.means[3 * size_t(v) + 1],
                               a.gaussians.means[3 * size_t(v) + 2]);
    EXPECT_LT((S.row(v).transpose() - (mean + r * n.row(v).transpose())).norm(), 1e-5) << v;
  }
  // The exported mesh (vertex colours: one glTF vertex per template vertex) is that surface.
  GltfExportOptions o;
  o.splats = false;
  o.vertex_colors = true;
  const GlbDocument d = parse_glb(avatar_gltf(a, {}, o), "m");
  const auto pos = d.read_floats(attr(d.gltf["meshes"][0]["primitives"][0], "POSITION"));
  ASSERT_EQ(pos.size(), size_t(3 * S.rows()));
  for (long v = 0; v < S.rows(); ++v)
    for (int k = 0; k < 3; ++k) EXPECT_FLOAT_EQ(pos[3 * size_t(v) + size_t(k)], float(S(v, k)));
}

TEST(Gltf, MeshOnlyAndSplatsOnly) {
  const Avatar a = test::tiny_avatar();
  GltfExportOptions mesh;
  mesh.splats = false;
  GlbDocument d = parse_glb(avatar_gltf(a, {}, mesh), "m");
  EXPECT_EQ(d.gltf["meshes"].size(), 1u);
  EXPECT_EQ(d.gltf["meshes"][0]["name"], "avatar_mesh");
  EXPECT_FALSE(d.gltf.contains("animations"));
  EXPECT_EQ(d.gltf["extensionsUsed"], nlohmann::json({"KHR_materials_unlit"}));
  GltfExportOptions splats;
  splats.mesh = false;
  d = parse_glb(avatar_gltf(a, {}, splats), "s");
  EXPECT_EQ(d.gltf["meshes"].size(), 1u);
  EXPECT_EQ(d.gltf["meshes"][0]["name"], "avatar_splats");
  GltfExportOptions none;
  none.mesh = none.splats = false;
  EXPECT_THROW(avatar_gltf(a, {}, none), Error);
}

TEST(Gltf, BakesVerticesWithoutGaussiansFromTheNearest) {
  Avatar a = test::tiny_avatar();
  // One extra template vertex no Gaussian hangs on, just beside vertex 2 (the top).
  a.template_vertices.conservativeResize(7, 3);
  a.template_vertices.row(6) << 0.01, 1.2, 0.0;
  const BakedVertexAttributes b = bake_vertex_attributes(a);
  for (int k = 0; k < 3; ++k) EXPECT_FLOAT_EQ(b.srgb[18 + size_t(k)], b.srgb[6 + size_t(k)]);
  EXPECT_EQ(b.joints[24], 2);
  EXPECT_FLOAT_EQ(b.weights[24], 1.f);
}

std::vector<uint8_t> small_glb() {
  GltfExportOptions o;
  o.mesh = false;
  return avatar_gltf(test::tiny_avatar(), {}, o);
}

void put32(std::vector<uint8_t>& b, size_t at, uint32_t v) {
  std::memcpy(&b[at], &v, 4);
}

TEST(Gltf, MalformedGlbIsAClearError) {
  const std::vector<uint8_t> good = small_glb();
  EXPECT_NO_THROW(parse_glb(good, "good"));
  auto expect_error = [](const std::vector<uint8_t>& b, const std::string& needle) {
    try {
      parse_glb(b, "bad.glb");
      ADD_FAILURE() << "no error for " << needle;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("bad.glb"), std::string::npos) << e.what();
    }
  };
  expect_error({}, "shorter than the GLB header");
  std::vector<uint8_t> b(good.begin(), good.begin() + long(good.size() / 2));
  expect_error(b, "truncated");
  b = good;
  b[0] = 'x';
  expect_error(b, "wrong magic");
  b = good;
  put32(b, 4, 1);
  expect_error(b, "version 1");
  b = good;
  put32(b, 12, uint32_t(good.size()));  // JSON chunk longer than the file
  expect_error(b, "remain");
  // JSON that is not an object, and JSON that does not parse.
  auto with_json = [](const std::string& text) {
    std::vector<uint8_t> out(20 + text.size());
    put32(out, 0, 0x46546C67);
    put32(out, 4, 2);
    put32(out, 8, uint32_t(out.size()));
    put32(out, 12, uint32_t(text.size()));
    put32(out, 16, 0x4E4F534A);
    std::memcpy(&out[20], text.data(), text.size());
    return out;
  };
  expect_error(with_json("[1, 2, 3]   "), "not an object");
  expect_error(with_json("{\"asset\": "), "malformed glTF JSON");
  EXPECT_NO_THROW(parse_glb(with_json("{}  "), "ok"));
  // An accessor pointing outside the BIN chunk.
  GlbDocument d = parse_glb(good, "acc.glb");
  d.gltf["bufferViews"][0]["byteLength"] = 1 << 30;
  EXPECT_THROW(d.read_floats(0), Error);
  EXPECT_THROW(d.read_floats(9999), Error);
  // Integer fields that are fractions, out of range or negative (fuzz_glb's finding: 5e26).
  for (const char* bad : {"5e26", "1.5", "-1", "\"3\""}) {
    GlbDocument e = parse_glb(good, "acc.glb");
    e.gltf["accessors"][0]["count"] = nlohmann::json::parse(bad);
    EXPECT_THROW(e.read_floats(0), Error) << bad;
    e = parse_glb(good, "acc.glb");
    e.gltf["bufferViews"][0]["byteOffset"] = nlohmann::json::parse(bad);
    EXPECT_THROW(e.read_floats(0), Error) << bad;
  }
  // A file that is missing.
  EXPECT_THROW(read_glb("/nonexistent/x.glb"), Error);
}

TEST(Gltf, CommandLine) {
  test::TempDir dir("gltf_cli");
  const std::string avatar = (dir.path() / "a.ksavatar").string();
  save_avatar(avatar, test::tiny_avatar());
  const std::string out = (dir.path() / "a.glb").string();
  test::CliRun r =
      test::run_cli("export '" + avatar + "' --gltf '" + out + "' --motion walk --motion wave");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.out.find("2 animations"), std::string::npos) << r.out;
  const GlbDocument d = read_glb(out);
  EXPECT_EQ(d.gltf["animations"].size(), 2u);
  EXPECT_EQ(d.gltf["meshes"].size(), 2u);
  // A motion as `track` writes it (motion.npz, AMASS layout) is an animation too.
  const std::string npz = (dir.path() / "motion.npz").string();
  save_amass_npz(npz, builtin_motion("wave", 5));
  r = test::run_cli("export '" + avatar + "' --gltf '" + out + "' --motion '" + npz + "'");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(read_glb(out).gltf["animations"][0]["extras"]["frames"], 5);
  r = test::run_cli("export '" + avatar + "' --gltf '" + out + "' --mesh --vertex-colors");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(read_glb(out).gltf["meshes"].size(), 1u);
  r = test::run_cli("export '" + avatar + "' --gltf '" + out + "' --mesh --splats");
  EXPECT_EQ(r.status, 1) << r.output;
  r = test::run_cli("export '" + avatar + "' --gltf '" + out + "' --pose p.json");
  EXPECT_EQ(r.status, 1) << r.output;
  r = test::run_cli("export '" + avatar + "' --out x.ply --mesh");
  EXPECT_EQ(r.status, 1) << r.output;
  r = test::run_cli("export '" + avatar + "' --gltf '" + (dir.path() / "b.glb").string() +
                    "' --motion no-such-motion");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_FALSE(fs::exists(dir.path() / "b.glb"));
}

}  // namespace
}  // namespace ks
