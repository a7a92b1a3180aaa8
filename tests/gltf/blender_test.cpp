// Blender (Debian's `blender`, 3.4.1, `make deps`) run headless imports kinesplat's exports:
// tests/gltf/blender/import_check.py imports a GLB of the default body's plain avatar with two
// motions (bpy.ops.import_scene.gltf) and a BVH of one of them (bpy.ops.import_anim.bvh) in one
// Blender run and reports what it made. The GLB must give an armature with a bone per joint, the
// mesh with the template's vertices and faces, a vertex group per joint and its colours, and one
// action per motion with a key per motion frame; the BVH must give the motion's per-joint local
// rotations back. Skips, saying why, where blender (or the numpy its glTF importer needs) is
// missing.
#include <gtest/gtest.h>

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <set>
#include <string>

#include "../temp_dir.hpp"
#include "avatar/from_body.hpp"
#include "avatar/pose.hpp"
#include "body/body_model.hpp"
#include "core/fileio.hpp"
#include "core/rotation.hpp"
#include "gltf/avatar_bvh.hpp"
#include "gltf/glb.hpp"
#include "gltf/gltf_export.hpp"
#include "motion/bvh.hpp"

namespace ks {
namespace {

namespace fs = std::filesystem;

Eigen::Matrix3d json_matrix(const nlohmann::json& m) {
  Eigen::Matrix3d r;
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) r(i, k) = m[size_t(i)][size_t(k)].get<double>();
  return r;
}

std::set<std::string> json_names(const nlohmann::json& list) {
  std::set<std::string> s;
  for (const auto& n : list) s.insert(n.get<std::string>());
  return s;
}

// The angle (radians) of the rotation taking a to b. b is a float32 matrix from Blender, a little
// off orthonormal, so it is replaced by its nearest rotation (U V^T of its SVD) first, and the
// angle is read from the antisymmetric part (|D - D^T| = 2 sqrt(2) sin angle), which keeps
// its precision for small angles.
double rotation_angle(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(b, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d d = a.transpose() * (svd.matrixU() * svd.matrixV().transpose());
  const double s = (d - d.transpose()).norm() / (2.0 * std::sqrt(2.0));
  const double angle = std::asin(std::min(1.0, s));
  return d.trace() < 1.0 ? M_PI - angle : angle;  // past 90 degrees (trace = 1 + 2 cos angle)
}

TEST(GltfBlender, ImportsTheAvatarAndTheBvhMotion) {
  if (std::system("command -v blender >/dev/null 2>&1") != 0)
    GTEST_SKIP()
        << "blender is not installed (Debian's package `blender`; `make deps` installs it)";
  PlainAvatarOptions opt;
  opt.posedirs = false;
  const Avatar a = avatar_from_body(default_body_model(), Eigen::VectorXd::Zero(2), opt);
  const int J = a.num_joints();
  ASSERT_EQ(a.joint_names.size(), size_t(J));
  const std::set<std::string> joints(a.joint_names.begin(), a.joint_names.end());
  const Motion walk = builtin_motion("walk", 12), wave = builtin_motion("wave", 8);
  test::TempDir tmp("gltf_blender");
  const std::string glb = tmp / "avatar.glb", bvh = tmp / "walk.bvh", out = tmp / "report.json";
  export_gltf(glb, a, {walk, wave});
  write_bvh(bvh, avatar_motion_bvh(a, walk));
  const std::vector<int> frames = {0, 5, 11};
  const std::string cmd =
      "blender -b --factory-startup -noaudio --python '" +
      (fs::path(KS_SOURCE_DIR) / "tests/gltf/blender/import_check.py").string() + "' -- --out '" +
      out + "' --glb '" + glb + "' --bvh '" + bvh + "' --bvh-frames 0,5,11 > '" + tmp / "log.txt" +
      "' 2>&1";
  const int rc = std::system(cmd.c_str());
  nlohmann::json r;
  try {
    r = nlohmann::json::parse(read_file_text(out));
  } catch (const std::exception&) {
    FAIL() << "Blender wrote no report (exit " << rc << "):\n" << read_file_text(tmp / "log.txt");
  }
  if (r.contains("numpy_error"))
    GTEST_SKIP() << "Blender's Python has no numpy, which its glTF importer needs (Debian's "
                    "python3-numpy): "
                 << r["numpy_error"].get<std::string>();
  ASSERT_FALSE(r.contains("error")) << r["error"].get<std::string>();
  std::printf("Blender %s, numpy %s (numpy.bool %s)\n", r.value("blender_version", "?").c_str(),
              r.value("numpy_version", "?").c_str(),
              r.value("numpy_patched", false) ? "set by the script" : "present");

  // The GLB.
  const auto& g = r["glb"];
  ASSERT_EQ(g["result"], nlohmann::json::array({"FINISHED"}))
      << g.value("error", nlohmann::json()).dump() << "\n"
      << g["importer_output"].dump(1);
  ASSERT_EQ(g["armatures"].size(), 1u) << g["objects"].dump(1);
  const auto& arm = g["armatures"][0];
  EXPECT_EQ(arm["bone_count"], J);
  EXPECT_EQ(json_names(arm["bones"]), joints);
  // The bones keep the skeleton: each bone's parent is its joint's parent.
  for (int j = 0; j < J; ++j) {
    const auto& p = arm["bone_parents"][a.joint_names[size_t(j)]];
    if (a.parents[size_t(j)] < 0)
      EXPECT_TRUE(p.is_null()) << a.joint_names[size_t(j)];
    else
      EXPECT_EQ(p, a.joint_names[size_t(a.parents[size_t(j)])]) << a.joint_names[size_t(j)];
  }
  const nlohmann::json* mesh = nullptr;
  const nlohmann::json* splats = nullptr;
  for (const auto& m : g["meshes"]) {
    if (m["mesh_name"] == "avatar_mesh") mesh = &m;
    if (m["mesh_name"] == "avatar_splats") splats = &m;
  }
  ASSERT_NE(mesh, nullptr) << g["meshes"].dump(1);
  const auto& me = *mesh;
  // The file's mesh vertices: the template's, plus, where the colour is a texture over a UV
  // atlas, copies of the vertices on chart borders (one per chart); at distinct positions they
  // are the template's vertices again.
  const GlbDocument doc = read_glb(glb);
  int file_vertices = -1;
  for (const auto& m : doc.gltf["meshes"])
    if (m["name"] == "avatar_mesh")
      file_vertices = doc.accessor_count(m["primitives"][0]["attributes"]["POSITION"].get<int>());
  EXPECT_EQ(me["vertices"], file_vertices);
  EXPECT_EQ(me["distinct_positions"], a.template_vertices.rows());
  EXPECT_EQ(me["polygons"], a.template_faces.rows());
  EXPECT_EQ(me["vertex_groups"], J);
  EXPECT_EQ(json_names(me["vertex_group_names"]), joints);
  EXPECT_EQ(me["weighted_vertices"], me["vertices"]);  // the skin reaches every vertex
  EXPECT_EQ(me["parent"], arm["name"]);
  bool textured = false;
  for (const auto& m : me["materials"]) textured = textured || !m["images"].empty();
  // The mesh's colours: COLOR_0 becomes a colour attribute; a texture atlas, an image in the
  // material and a UV layer.
  EXPECT_TRUE(me["has_color"].get<bool>() || (textured && !me["uv_layers"].empty())) << me.dump(1);
  // Blender knows nothing of KHR_gaussian_splatting: the POINTS primitive becomes a mesh of loose
  // vertices (one per Gaussian, no edges or faces) skinned to the same armature; its COLOR_0
  // becomes a colour attribute on the face corners, of which a mesh without faces has none, so the
  // colours are lost.
  ASSERT_NE(splats, nullptr) << g["meshes"].dump(1);
  EXPECT_EQ((*splats)["vertices"], a.num_gaussians());
  EXPECT_EQ((*splats)["polygons"], 0);
  EXPECT_EQ((*splats)["edges"], 0);
  EXPECT_EQ((*splats)["vertex_groups"], J);
  EXPECT_EQ((*splats)["parent"], arm["name"]);
  EXPECT_TRUE(g["point_clouds"].empty());
  // One action per motion, stashed on an NLA track named after it, with a key per motion frame:
  // the importer keys glTF time t = frame / fps at Blender frame t * the scene's fps (24).
  ASSERT_EQ(g["actions"].size(), 2u) << g["actions"].dump(1);
  ASSERT_EQ(arm["nla_tracks"].size(), 2u) << arm.dump(1);
  for (const Motion* m : {&walk, &wave}) {
    const nlohmann::json* track = nullptr;
    for (const auto& t : arm["nla_tracks"])
      if (t["name"] == m->name) track = &t;
    ASSERT_NE(track, nullptr) << m->name << ": " << arm["nla_tracks"].dump(1);
    ASSERT_EQ((*track)["strips"].size(), 1u);
    const nlohmann::json* act = nullptr;
    for (const auto& x : g["actions"])
      if (x["name"] == (*track)["strips"][0]) act = &x;
    ASSERT_NE(act, nullptr);
    const int F = int(m->frames.size());
    EXPECT_EQ((*act)["key_times"], F) << m->name;
    EXPECT_EQ((*act)["keys_per_fcurve"], nlohmann::json::array({F})) << m->name;
    // A rotation (4 curves) per bone and the root's location (3).
    EXPECT_EQ((*act)["fcurves"], 4 * J + 3) << m->name;
    EXPECT_NEAR((*act)["frame_range"][0].get<double>(), 0.0, 1e-4) << m->name;
    EXPECT_NEAR((*act)["frame_range"][1].get<double>(), (F - 1) / m->fps * 24.0, 1e-3) << m->name;
    std::printf("glTF action %s: %d keys, Blender frames %.3f..%.3f\n",
                (*act)["name"].get<std::string>().c_str(), (*act)["key_times"].get<int>(),
                (*act)["frame_range"][0].get<double>(), (*act)["frame_range"][1].get<double>());
  }
  std::printf(
      "glTF import %.2f s: armature %d bones; mesh %d vertices (%d positions), %d faces, "
      "%d groups, %s; splats: %d loose vertices\n",
      g["import_seconds"].get<double>(), arm["bone_count"].get<int>(), me["vertices"].get<int>(),
      me["distinct_positions"].get<int>(), me["polygons"].get<int>(),
      me["vertex_groups"].get<int>(), textured ? "a textured material" : "a colour attribute",
      (*splats)["vertices"].get<int>());

  // The BVH: the importer's armature (a bone per joint), a key per frame, and each joint's local
  // rotation, taken from Blender's evaluated pose with its rest orientation and axis conversion
  // undone (import_check.py bvh_rotations), equal to the motion's. The file's Euler angles have 6
  // decimals (1e-8 rad of rounding); the rest is Blender's float32: its bone rest matrices, built
  // from head, tail and roll, are up to 5.7e-5 off orthonormal here (reported), and the importer's
  // keys P = B^-1 R B pass that on scaled by the rotation's size. Measured: 1.9e-5 rad at worst,
  // the root's head 4.3e-5 m off (on the demo avatar's 64-frame walk: 4.0e-6 rad, 9.4e-6 m). 1e-4
  // rad (0.006 degrees) and 1e-4 m are five times that and far below a real mismatch: a swapped
  // Euler order, a missed axis conversion or a flipped sign puts the worst joint of the walk
  // 0.27, 1.5 or 2.2 rad off.
  const auto& b = r["bvh"];
  ASSERT_EQ(b["result"], nlohmann::json::array({"FINISHED"}))
      << b.value("error", nlohmann::json()).dump() << "\n"
      << b["importer_output"].dump(1);
  EXPECT_EQ(b["bone_count"], J);
  EXPECT_EQ(json_names(b["bones"]), joints);
  EXPECT_EQ(b["frames"], int(walk.frames.size()));
  const Eigen::Matrix3d C = json_matrix(b["axis_conversion"]);
  double worst = 0, worst_position = 0;
  for (int f : frames) {
    const Eigen::MatrixXd pose = avatar_full_pose(a, walk.frames[size_t(f)]);
    const auto& rf = b["rotations"][std::to_string(f)];
    for (int j = 0; j < J; ++j) {
      const std::string& name = a.joint_names[size_t(j)];
      ASSERT_TRUE(rf.contains(name)) << name;
      const Eigen::Matrix3d want = axis_angle_to_matrix(Eigen::Vector3d(pose.row(j).transpose()));
      const double d = rotation_angle(want, json_matrix(rf[name]["matrix"]));
      EXPECT_LT(d, 1e-4) << name << " frame " << f;
      worst = std::max(worst, d);
    }
    // The root bone's head: the root joint's world position (rest + transl) in the BVH's axes.
    const auto& loc = rf[a.joint_names[0]]["location"];
    const Eigen::Vector3d head =
        C.transpose() *
        Eigen::Vector3d(loc[0].get<double>(), loc[1].get<double>(), loc[2].get<double>());
    const Eigen::Vector3d want_head =
        a.rest_joints.row(0).transpose() + walk.frames[size_t(f)].transl;
    worst_position = std::max(worst_position, (head - want_head).norm());
    EXPECT_LT((head - want_head).norm(), 1e-4) << "frame " << f;
  }
  std::printf(
      "BVH import %.3f s: %d bones, %d frames; local rotations at frames 0, 5, 11 within "
      "%.2e rad of the motion's, root within %.2e m (Blender's rest matrices %.1e off "
      "orthonormal)\n",
      b["import_seconds"].get<double>(), b["bone_count"].get<int>(), b["frames"].get<int>(), worst,
      worst_position, b["rest_orthonormality_error"].get<double>());
}

}  // namespace
}  // namespace ks
