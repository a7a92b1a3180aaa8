// BVH (motion/bvh.hpp, motion/bvh_motion.hpp): the text format's round trip and malformed files,
// a motion's round trip export -> import (the same joint rotations), and Mixamo- and CMU-named
// hierarchies the test writes itself, retargeted through their rest poses.
#include "motion/bvh.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <random>

#include "../avatar/tiny_avatar.hpp"
#include "../cli_run.hpp"
#include "../temp_dir.hpp"
#include "avatar/avatar.hpp"
#include "body/body_model.hpp"
#include "body/joints.hpp"
#include "body/posing.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "core/rotation.hpp"
#include "motion/bvh_motion.hpp"
#include "motion/motion.hpp"

namespace ks {
namespace {

namespace fs = std::filesystem;

Eigen::MatrixXd body_rest() {
  const BodyModel& m = default_body_model();
  return m.J_regressor * m.v_template;
}

Eigen::MatrixXd full_pose(const BodyParams& p) {
  Eigen::MatrixXd pose(24, 3);
  pose.row(0) = p.global_orient.transpose();
  for (int j = 1; j < 24; ++j) pose.row(j) = p.body_pose.segment<3>(3 * (j - 1)).transpose();
  return pose;
}

Bvh walk_bvh(int frames) {
  const Motion walk = builtin_motion("walk", frames);
  std::vector<Eigen::MatrixXd> poses;
  std::vector<Eigen::Vector3d> transl;
  for (const auto& f : walk.frames) {
    poses.push_back(full_pose(f));
    transl.push_back(f.transl);
  }
  return poses_to_bvh(smpl_parents(), default_body_model().joint_names, body_rest(), poses, transl,
                      walk.fps);
}

TEST(Bvh, TextRoundTrip) {
  const Bvh b = walk_bvh(12);
  const Bvh r = parse_bvh(format_bvh(b), "mem.bvh");
  ASSERT_EQ(r.joints.size(), b.joints.size());
  for (size_t j = 0; j < b.joints.size(); ++j) {
    EXPECT_EQ(r.joints[j].name, b.joints[j].name);
    EXPECT_EQ(r.joints[j].parent, b.joints[j].parent);
    EXPECT_EQ(r.joints[j].channels, b.joints[j].channels);
    EXPECT_EQ(r.joints[j].first_channel, b.joints[j].first_channel);
    EXPECT_EQ(r.joints[j].has_end_site, b.joints[j].has_end_site);
    EXPECT_LT((r.joints[j].offset - b.joints[j].offset).norm(), 1e-6);
    EXPECT_LT((r.joints[j].end_site - b.joints[j].end_site).norm(), 1e-6);
  }
  EXPECT_NEAR(r.frame_time, b.frame_time, 1e-8);
  ASSERT_EQ(r.frames.rows(), 12);
  EXPECT_LT((r.frames - b.frames).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_EQ(r.num_channels(), 6 + 3 * 23);
  EXPECT_EQ(r.joints[0].name, "pelvis");
}

TEST(Bvh, ExportImportGivesTheSameJointRotations) {
  const Motion walk = builtin_motion("walk", 20);
  test::TempDir dir("bvh_rt");
  const std::string path = (dir.path() / "walk.bvh").string();
  write_bvh(path, walk_bvh(20));
  const Motion m = load_motion(path);  // the one motion loader, .bvh dispatched
  EXPECT_EQ(m.name, "walk");
  EXPECT_NEAR(m.fps, walk.fps, 1e-6);
  ASSERT_EQ(m.frames.size(), walk.frames.size());
  double worst = 0, worst_t = 0;
  for (size_t f = 0; f < m.frames.size(); ++f) {
    const Eigen::MatrixXd a = full_pose(walk.frames[f]), b = full_pose(m.frames[f]);
    for (int j = 0; j < 24; ++j)
      worst = std::max(worst, (axis_angle_to_matrix<double>(a.row(j).transpose()) -
                               axis_angle_to_matrix<double>(b.row(j).transpose()))
                                  .norm());
    // The translation relative to frame 0, at the same scale (the same legs).
    worst_t = std::max(
        worst_t, ((walk.frames[f].transl - walk.frames[0].transl) - m.frames[f].transl).norm());
  }
  EXPECT_LT(worst, 1e-6);
  EXPECT_LT(worst_t, 1e-6);
}

TEST(Bvh, SmplNamedFilesKeepTheirRotationsOnAnotherShape) {
  // The same poses on a body with other proportions (longer legs, wider shoulders).
  Eigen::MatrixXd rest = body_rest();
  for (int j = 1; j < 24; ++j) rest.row(j).x() *= 1.3;
  for (int j : {1, 2, 4, 5, 7, 8, 10, 11}) rest.row(j).y() -= 0.1 * (j > 3);
  const Motion walk = builtin_motion("walk", 5);
  std::vector<Eigen::MatrixXd> poses;
  std::vector<Eigen::Vector3d> transl;
  for (const auto& f : walk.frames) {
    poses.push_back(full_pose(f));
    transl.push_back(f.transl);
  }
  const Bvh b =
      poses_to_bvh(smpl_parents(), default_body_model().joint_names, rest, poses, transl, walk.fps);
  const Motion m =
      bvh_to_motion(parse_bvh(format_bvh(b), "shaped.bvh"), "shaped", smpl_parents(), body_rest());
  for (size_t f = 0; f < m.frames.size(); ++f) {
    const Eigen::MatrixXd a = full_pose(walk.frames[f]), c = full_pose(m.frames[f]);
    for (int j = 0; j < 24; ++j)
      EXPECT_LT((axis_angle_to_matrix<double>(a.row(j).transpose()) -
                 axis_angle_to_matrix<double>(c.row(j).transpose()))
                    .norm(),
                1e-6);
  }
}

// A BVH on SMPL's structure with the given names per SMPL joint (22 body joints; "" = skipped,
// its child then hangs on its parent), extra zero-offset joints inserted above some joints
// (`insert_above`: name -> the extra joint's name), rest positions scaled by `scale`, the arms
// rotated down by `arm_down` degrees about Z in the rest pose, rotation channels in `order`.
struct BvhSpec {
  std::vector<std::string> names;
  std::vector<std::pair<std::string, std::string>> insert_above;
  double scale = 1;
  double arm_down = 0;
  std::vector<BvhChannel> order = {BvhChannel::kZrot, BvhChannel::kYrot, BvhChannel::kXrot};
};

Bvh make_bvh(const BvhSpec& s, int frames, unsigned seed) {
  const Eigen::MatrixXd rest = body_rest();
  const auto& parents = smpl_parents();
  Eigen::MatrixXd P = rest.topRows(22) * s.scale;
  // A-pose: each arm chain (collar's children) turned down about the shoulder.
  for (int side = 0; side < 2; ++side) {
    const int sh = side == 0 ? smpl_joint::kLeftShoulder : smpl_joint::kRightShoulder;
    const double a = (side == 0 ? -1 : 1) * s.arm_down * M_PI / 180;
    const Eigen::Matrix3d R = Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    for (int j : {sh, sh + 2, sh + 4}) {
      const Eigen::Vector3d o = P.row(sh).transpose();
      P.row(j) = (o + R * (P.row(j).transpose() - o)).transpose();
    }
  }
  Bvh b;
  std::vector<int> index(22, -1);
  int channel = 0;
  std::function<void(int)> add = [&](int j) {
    int parent = -1;
    for (int p = parents[size_t(j)]; p >= 0; p = parents[size_t(p)])
      if (index[size_t(p)] >= 0) {
        parent = index[size_t(p)];
        break;
      }
    const Eigen::Vector3d pp = parents[size_t(j)] >= 0
                                   ? Eigen::Vector3d(P.row(parents[size_t(j)]).transpose())
                                   : Eigen::Vector3d::Zero();
    for (const auto& [above, extra] : s.insert_above)
      if (above == s.names[size_t(j)]) {
        BvhJoint e;
        e.name = extra;
        e.parent = parent;
        e.offset = Eigen::Vector3d::Zero();
        e.channels = s.order;
        e.first_channel = channel;
        channel += 3;
        b.joints.push_back(e);
        parent = int(b.joints.size()) - 1;
      }
    BvhJoint bj;
    bj.name = s.names[size_t(j)];
    bj.parent = parent;
    bj.offset = parent < 0 ? Eigen::Vector3d::Zero() : Eigen::Vector3d(P.row(j).transpose() - pp);
    if (parent < 0) bj.channels = {BvhChannel::kXpos, BvhChannel::kYpos, BvhChannel::kZpos};
    for (BvhChannel c : s.order) bj.channels.push_back(c);
    bj.first_channel = channel;
    channel += int(bj.channels.size());
    bool leaf = true;
    for (int c = 0; c < 22; ++c)
      if (parents[size_t(c)] == j) leaf = false;
    if (leaf) {
      bj.has_end_site = true;
      bj.end_site = Eigen::Vector3d(0, 0.05 * s.scale, 0);
    }
    b.joints.push_back(bj);
    index[size_t(j)] = int(b.joints.size()) - 1;
    for (int c = 0; c < 22; ++c)
      if (parents[size_t(c)] == j) add(c);
  };
  add(0);
  b.frame_time = 1.0 / 30;
  b.frames = Eigen::MatrixXd::Zero(frames, channel);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-40, 40);
  for (int f = 1; f < frames; ++f) {  // frame 0: the rest pose
    for (int c = 0; c < channel; ++c) b.frames(f, c) = u(rng);
    b.frames(f, 0) = f * s.scale;  // the root walks 1 m (in the file's units) per frame along X
    b.frames(f, 1) = P(0, 1);
    b.frames(f, 2) = 0;
  }
  b.frames(0, 1) = P(0, 1);
  return b;
}

// Every mapped body bone (joint -> its first child) whose BVH joints are parent and child points
// the same way in the posed body as in the posed BVH, in every frame.
void expect_bones_follow(const Bvh& bvh, const Motion& m, double tol, int bones_per_frame = 8) {
  const std::vector<int> map = map_bvh_to_smpl(bvh, "test");
  const auto& parents = smpl_parents();
  const Eigen::MatrixXd rest = body_rest();
  int checked = 0;
  for (size_t f = 0; f < m.frames.size(); ++f) {
    const auto sk =
        forward_kinematics<double>(parents, rest, full_pose(m.frames[f]), Eigen::Vector3d::Zero());
    // The BVH's posed joint positions.
    std::vector<Eigen::Matrix3d> G(bvh.joints.size());
    std::vector<Eigen::Vector3d> X(bvh.joints.size());
    for (size_t k = 0; k < bvh.joints.size(); ++k) {
      const int p = bvh.joints[k].parent;
      const Eigen::Matrix3d L = bvh.local_rotation(int(k), int(f));
      const Eigen::Vector3d t = bvh.local_translation(int(k), int(f));
      G[k] = p < 0 ? L : Eigen::Matrix3d(G[size_t(p)] * L);
      X[k] = p < 0 ? t : Eigen::Vector3d(X[size_t(p)] + G[size_t(p)] * t);
    }
    for (int j = 1; j < 22; ++j) {
      const int c = first_child(parents, j);
      if (c < 0 || c >= 22 || map[size_t(j)] < 0 || map[size_t(c)] < 0) continue;
      if (bvh.joints[size_t(map[size_t(c)])].parent != map[size_t(j)]) continue;
      const Eigen::Vector3d db = (sk.joints.row(c) - sk.joints.row(j)).transpose().normalized();
      const Eigen::Vector3d dv =
          (X[size_t(map[size_t(c)])] - X[size_t(map[size_t(j)])]).normalized();
      EXPECT_LT((db - dv).norm(), tol) << "frame " << f << " joint " << j;
      ++checked;
    }
  }
  EXPECT_GE(checked, int(m.frames.size()) * bones_per_frame);
}

TEST(Bvh, MixamoNamedHierarchyInCentimetres) {
  BvhSpec s;
  s.names = {"mixamorig:Hips",        "mixamorig:LeftUpLeg",    "mixamorig:RightUpLeg",
             "mixamorig:Spine",       "mixamorig:LeftLeg",      "mixamorig:RightLeg",
             "mixamorig:Spine1",      "mixamorig:LeftFoot",     "mixamorig:RightFoot",
             "mixamorig:Spine2",      "mixamorig:LeftToeBase",  "mixamorig:RightToeBase",
             "mixamorig:Neck",        "mixamorig:LeftShoulder", "mixamorig:RightShoulder",
             "mixamorig:Head",        "mixamorig:LeftArm",      "mixamorig:RightArm",
             "mixamorig:LeftForeArm", "mixamorig:RightForeArm", "mixamorig:LeftHand",
             "mixamorig:RightHand"};
  s.scale = 100;  // centimetres
  s.order = {BvhChannel::kZrot, BvhChannel::kXrot, BvhChannel::kYrot};
  test::TempDir dir("bvh_mixamo");
  const std::string path = (dir.path() / "mixamo_walk.bvh").string();
  write_bvh(path, make_bvh(s, 8, 1));
  const Bvh bvh = read_bvh(path);
  const std::vector<int> map = map_bvh_to_smpl(bvh, path);
  for (int j = 0; j < 22; ++j) {
    ASSERT_GE(map[size_t(j)], 0) << j;
    EXPECT_EQ(bvh.joints[size_t(map[size_t(j)])].name, s.names[size_t(j)]);
  }
  EXPECT_EQ(map[22], -1);
  const Motion m = load_motion(path);
  ASSERT_EQ(m.frames.size(), 8u);
  // Same rest geometry (scaled): frame 0 is the body's rest pose.
  EXPECT_LT(full_pose(m.frames[0]).norm(), 1e-6);
  expect_bones_follow(bvh, m, 1e-6);
  // 100 cm a frame is 1 m a frame on the body (the legs' ratio).
  EXPECT_NEAR(m.frames[3].transl.x(), 3.0, 1e-6);
  EXPECT_NEAR(m.frames[3].transl.y(), 0.0, 1e-6);
}

TEST(Bvh, CmuNamedHierarchyInInchesWithAnAPoseRest) {
  BvhSpec s;
  s.names = {"Hips",        "LeftUpLeg",    "RightUpLeg", "LowerBack",    "LeftLeg",
             "RightLeg",    "Spine",        "LeftFoot",   "RightFoot",    "Spine1",
             "LeftToeBase", "RightToeBase", "Neck",       "LeftShoulder", "RightShoulder",
             "Head",        "LeftArm",      "RightArm",   "LeftForeArm",  "RightForeArm",
             "LeftHand",    "RightHand"};
  s.insert_above = {{"LeftUpLeg", "LHipJoint"}, {"RightUpLeg", "RHipJoint"}, {"Head", "Neck1"}};
  s.scale = 1 / 0.0254;  // inches
  s.arm_down = 45;
  test::TempDir dir("bvh_cmu");
  const std::string path = (dir.path() / "cmu.bvh").string();
  write_bvh(path, make_bvh(s, 8, 2));
  const Bvh bvh = read_bvh(path);
  EXPECT_EQ(bvh.find("LHipJoint"), 1);
  const Motion m = load_motion(path);
  ASSERT_EQ(m.frames.size(), 8u);
  // The rest frame puts the body's arms down 45 degrees (through the rest poses), legs unchanged.
  const auto sk = forward_kinematics<double>(smpl_parents(), body_rest(), full_pose(m.frames[0]),
                                             Eigen::Vector3d::Zero());
  using namespace smpl_joint;
  const Eigen::Vector3d arm =
      (sk.joints.row(kLeftElbow) - sk.joints.row(kLeftShoulder)).transpose().normalized();
  const Eigen::Vector3d rest_arm =
      (body_rest().row(kLeftElbow) - body_rest().row(kLeftShoulder)).transpose().normalized();
  EXPECT_NEAR(std::acos(std::clamp(arm.dot(rest_arm), -1.0, 1.0)) * 180 / M_PI, 45.0, 0.5);
  EXPECT_LT(arm.y(), -0.5);
  EXPECT_LT(full_pose(m.frames[0]).row(kLeftKnee).norm(), 1e-6);
  expect_bones_follow(bvh, m, 1e-6);
  EXPECT_NEAR(m.frames[2].transl.x(), 2.0, 1e-6);
}

TEST(Bvh, PoserNamesMapToo) {
  const std::string text =
      "HIERARCHY\nROOT hip\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n"
      " JOINT abdomen\n {\n  OFFSET 0 10 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n"
      "  JOINT chest\n  {\n   OFFSET 0 20 0\n   CHANNELS 3 Zrotation Xrotation Yrotation\n"
      "   JOINT lShldr\n   {\n    OFFSET 15 5 0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n"
      "    JOINT lForeArm\n    {\n     OFFSET 25 0 0\n     CHANNELS 3 Zrotation Xrotation "
      "Yrotation\n"
      "     End Site\n     {\n      OFFSET 20 0 0\n     }\n    }\n   }\n"
      "   JOINT rShldr\n   {\n    OFFSET -15 5 0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n"
      "    JOINT rForeArm\n    {\n     OFFSET -25 0 0\n     CHANNELS 3 Zrotation Xrotation "
      "Yrotation\n"
      "     End Site\n     {\n      OFFSET -20 0 0\n     }\n    }\n   }\n  }\n }\n"
      " JOINT lThigh\n {\n  OFFSET 8 -5 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n"
      "  JOINT lShin\n  {\n   OFFSET 0 -40 0\n   CHANNELS 3 Zrotation Xrotation Yrotation\n"
      "   JOINT lFoot\n   {\n    OFFSET 0 -40 0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n"
      "    End Site\n    {\n     OFFSET 0 0 10\n    }\n   }\n  }\n }\n"
      " JOINT rThigh\n {\n  OFFSET -8 -5 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n"
      "  JOINT rShin\n  {\n   OFFSET 0 -40 0\n   CHANNELS 3 Zrotation Xrotation Yrotation\n"
      "   JOINT rFoot\n   {\n    OFFSET 0 -40 0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n"
      "    End Site\n    {\n     OFFSET 0 0 10\n    }\n   }\n  }\n }\n}\n"
      "MOTION\nFrames: 2\nFrame Time: 0.033333\n";
  std::string frames;
  for (int f = 0; f < 2; ++f) {
    for (int c = 0; c < 39; ++c) {
      if (c) frames += ' ';
      frames += std::to_string(f * (c % 7) * 3.0);
    }
    frames += "\n";
  }
  const Bvh bvh = parse_bvh(text + frames, "poser.bvh");
  const std::vector<int> map = map_bvh_to_smpl(bvh, "poser.bvh");
  using namespace smpl_joint;
  EXPECT_EQ(bvh.joints[size_t(map[kLeftShoulder])].name, "lShldr");
  EXPECT_EQ(bvh.joints[size_t(map[kRightKnee])].name, "rShin");
  EXPECT_EQ(bvh.joints[size_t(map[kSpine3])].name, "chest");
  EXPECT_EQ(map[kSpine2], -1);
  const Motion m = bvh_to_motion(bvh, "poser", smpl_parents(), body_rest());
  ASSERT_EQ(m.frames.size(), 2u);
  EXPECT_LT(m.frames[1].transl.norm(), 1e-12);  // a root without position channels stays put
  expect_bones_follow(bvh, m, 1e-6, 6);
}

TEST(Bvh, MalformedFilesAreClearErrors) {
  const std::string good = format_bvh(walk_bvh(3));
  EXPECT_NO_THROW(parse_bvh(good, "good.bvh"));
  auto expect_error = [](const std::string& text, const std::string& needle) {
    try {
      parse_bvh(text, "bad.bvh");
      ADD_FAILURE() << "no error for " << needle;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("bad.bvh"), std::string::npos) << e.what();
    }
  };
  auto replace = [&](std::string from, std::string to) {
    std::string s = good;
    const size_t at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return s.replace(at, from.size(), to);
  };
  expect_error("", "no HIERARCHY");
  expect_error("hello\n", "no HIERARCHY");
  expect_error(replace("ROOT pelvis", "JOINT pelvis"), "expected ROOT");
  expect_error(replace("Zrotation", "Wrotation"), "unknown channel");
  expect_error(replace("CHANNELS 6", "CHANNELS 5"), "CHANNELS count");
  expect_error(replace("CHANNELS 6", "CHANNELS six"), "not a finite number");
  expect_error(replace("Frame Time: 0.", "Frame Time: -0."), "positive");
  expect_error(replace("Frames: 3", "Frames: 4"), "truncated");
  expect_error(replace("MOTION", "}\nMOTION"), "expected MOTION");
  expect_error(good.substr(0, good.find("MOTION")), "expected MOTION");
  expect_error(good.substr(0, good.find("JOINT spine2")), "unbalanced braces");
  expect_error(replace("OFFSET", "OFFSET 1"), "OFFSET needs 3 numbers");
  // A frame with a value too few, and one that is not a number.
  std::string s = good;
  s.erase(s.find_last_of(' ', s.size() - 2));
  expect_error(s + "\n", "values");
  s = good;
  s.replace(s.rfind(' ') + 1, std::string::npos, "nan\n");
  expect_error(s, "not a finite number");
  EXPECT_THROW(read_bvh("/nonexistent/x.bvh"), Error);
  // A skeleton that cannot be mapped names the joints it could not place.
  const Bvh odd = parse_bvh(
      "HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 3 Xrotation Yrotation Zrotation\n"
      " End Site\n {\n  OFFSET 0 1 0\n }\n}\nMOTION\nFrames: 1\nFrame Time: 0.1\n0 0 0\n",
      "odd.bvh");
  try {
    map_bvh_to_smpl(odd, "odd.bvh");
    ADD_FAILURE() << "mapped a one-joint skeleton";
  } catch (const Error& e) {
    const std::string w = e.what();
    EXPECT_NE(w.find("odd.bvh"), std::string::npos) << w;
    EXPECT_NE(w.find("pelvis"), std::string::npos) << w;
    EXPECT_NE(w.find("left_knee"), std::string::npos) << w;
    EXPECT_NE(w.find("the file's joints: A"), std::string::npos) << w;
  }
}

TEST(Bvh, CommandLineExportAndImport) {
  test::TempDir dir("bvh_cli");
  const std::string avatar = (dir.path() / "a.ksavatar").string();
  save_avatar(avatar, test::tiny_avatar());
  const std::string out = (dir.path() / "walk.bvh").string();
  test::CliRun r = test::run_cli("export '" + avatar + "' --bvh '" + out + "' --motion walk");
  ASSERT_EQ(r.status, 0) << r.output;
  const Bvh b = read_bvh(out);
  EXPECT_EQ(b.joints.size(), 3u);
  EXPECT_EQ(b.joints[2].name, "head");
  EXPECT_EQ(b.frames.rows(), long(builtin_motion("walk").frames.size()));
  r = test::run_cli("export '" + avatar + "' --bvh '" + out + "' --motion walk --motion wave");
  EXPECT_EQ(r.status, 1) << r.output;
  r = test::run_cli("export '" + avatar + "' --bvh '" + out + "'");
  EXPECT_EQ(r.status, 1) << r.output;
  // A body-skeleton BVH drives a glTF export's animation and the motions command.
  const std::string body_bvh = (dir.path() / "body_walk.bvh").string();
  write_bvh(body_bvh, walk_bvh(6));
  r = test::run_cli("export '" + avatar + "' --gltf '" + (dir.path() / "a.glb").string() +
                    "' --motion '" + body_bvh + "'");
  EXPECT_EQ(r.status, 0) << r.output;
  r = test::run_cli("motions --show '" + body_bvh + "'");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.out.find("body_walk"), std::string::npos);
  r = test::run_cli("motions --show '" + (dir.path() / "missing.bvh").string() + "'");
  EXPECT_EQ(r.status, 1) << r.output;
}

}  // namespace
}  // namespace ks
