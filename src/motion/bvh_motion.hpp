#pragma once
// BVH motions on the body (motion/bvh.hpp is the file format): a BVH skeleton mapped onto SMPL's
// 24 joints by name, and a skeleton's poses written as BVH.
//
// Names: the common conventions are told apart by their joints (names compared without case, a
// "prefix:" such as Mixamo's "mixamorig:", underscores and spaces):
//   SMPL     pelvis, left_hip, left_knee, left_ankle, left_foot, spine1..3, neck, head,
//            left_collar, left_shoulder, left_elbow, left_wrist, left_hand (and right_*)
//   Mixamo   Hips, LeftUpLeg, LeftLeg, LeftFoot, LeftToeBase, Spine (spine1), Spine1 (spine2),
//            Spine2 (spine3), Neck, Head, LeftShoulder (collar), LeftArm (shoulder), LeftForeArm,
//            LeftHand (wrist)
//   CMU      as Mixamo but LowerBack (spine1), Spine (spine2), Spine1 (spine3); LHipJoint, Neck1,
//            LeftFingerBase, ... are not mapped (their rotations still reach the mapped joints)
//   Poser    hip, abdomen (spine1), chest (spine3), neck, head, lCollar, lShldr, lForeArm, lHand,
//            lThigh, lShin, lFoot
// Retargeting through the rest poses: with every channel zero the BVH stands in its own rest pose
// (its OFFSETs); each mapped body joint gets a rest correction Q_j, the rotation that carries the
// body's rest bone (joint -> its first child) onto the BVH's rest bone (accumulated down the chain;
// the root's aligns the up and left-right axes), and in each frame the body joint's world rotation
// is the BVH joint's world rotation times Q_j. Unmapped body joints keep their parent's rotation.
// SMPL-named files (kinesplat's own `export --bvh`) are SMPL poses, shape-independent: their
// rotations are taken as they are (no rest correction), whichever body's offsets they carry.
// The root's translation is the mapped pelvis joint's motion relative to frame 0, scaled by the
// ratio of the body's left leg length (hip -> knee -> ankle) to the BVH's, so centimetre, inch
// and metre files all move the body by its own stride (SMPL-named files: unscaled metres, as
// AMASS's, unless their legs are off by more than a factor 2). A frame time within 1e-4 of a
// whole frame rate is read as that rate (0.033333 s: 30 fps). The BVH's world must be Y up (the
// convention; kinesplat's too).
#include <Eigen/Core>
#include <string>
#include <vector>

#include "motion/bvh.hpp"
#include "motion/motion.hpp"

namespace ks {

// The BVH joint mapped to each of SMPL's 24 joints (-1: none). Throws ks::Error naming `what`
// and the body joints it could not place (and the file's joint names) when the pelvis, a hip,
// knee, ankle, shoulder or elbow is missing. `convention` (optional): "SMPL", "Mixamo", "CMU" or
// "Poser", the names the file was read with.
std::vector<int> map_bvh_to_smpl(const Bvh& bvh, const std::string& what,
                                 std::string* convention = nullptr);

// The BVH as a Motion on the skeleton (parents, rest_joints: SMPL's 24 joints), named `name`.
// frames > 0: keep at most this many (after subsampling files above 45 fps to about 30 fps).
Motion bvh_to_motion(const Bvh& bvh, const std::string& name, const std::vector<int>& parents,
                     const Eigen::MatrixXd& rest_joints, int frames = 0,
                     const std::string& what = "bvh");
// A .bvh file onto the default body's skeleton (what load_motion does with a .bvh).
Motion load_bvh_motion(const std::string& path, int frames = 0);

// A skeleton's poses as BVH: joints named `names`, OFFSETs from the rest joints (metres; the
// root's 0, its position channels the root joint's world position rest_0 + transl), channels
// Xposition Yposition Zposition on the root, Zrotation Yrotation Xrotation on every joint (the
// local rotation R = Rz Ry Rx of each pose row's axis-angle), an End Site on every leaf (half its
// bone on along the same direction). poses: per frame J x 3 axis-angles.
Bvh poses_to_bvh(const std::vector<int>& parents, const std::vector<std::string>& names,
                 const Eigen::MatrixXd& rest_joints, const std::vector<Eigen::MatrixXd>& poses,
                 const std::vector<Eigen::Vector3d>& transl, double fps);

}  // namespace ks
