#pragma once
// BVH (Biovision hierarchy) motion files: the text format itself (read and write), with no
// meaning attached. HIERARCHY: ROOT / JOINT blocks with OFFSET (the joint's rest position relative
// to its parent, in the file's units), CHANNELS (Xposition Yposition Zposition Xrotation
// Yrotation Zrotation, any subset in any order) and End Site blocks (an OFFSET only); MOTION:
// "Frames: N", "Frame Time: T" (seconds) and N lines of one value per channel in hierarchy order.
// A joint's local rotation is the product of its rotation channels in the order listed
// (R = R_c1(a1) R_c2(a2) R_c3(a3), angles in degrees); its local translation is its OFFSET plus its
// position channels. Mapping a BVH onto the body: motion/bvh_motion.hpp. Documented in
// docs/export.md.
#include <Eigen/Core>
#include <string>
#include <vector>

namespace ks {

enum class BvhChannel { kXpos, kYpos, kZpos, kXrot, kYrot, kZrot };

struct BvhJoint {
  std::string name;
  int parent = -1;  // index into Bvh::joints; -1 for the root
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  std::vector<BvhChannel> channels;
  bool has_end_site = false;
  Eigen::Vector3d end_site = Eigen::Vector3d::Zero();  // the End Site's OFFSET, if any
  int first_channel = 0;                               // column of channels[0] in a frame
};

struct Bvh {
  std::vector<BvhJoint> joints;  // hierarchy order (parents before children), one root
  double frame_time = 1.0 / 30;  // seconds
  Eigen::MatrixXd frames;        // F x (total channels)

  int num_channels() const;
  // Joint j's local rotation in frame f (channels' product; identity without rotation channels).
  Eigen::Matrix3d local_rotation(int j, int f) const;
  // Joint j's local translation in frame f (OFFSET + position channels).
  Eigen::Vector3d local_translation(int j, int f) const;
  // Rest positions (all channels zero): each joint's accumulated offsets (J x 3).
  Eigen::MatrixXd rest_positions() const;
  // The index of the joint called `name`, or -1.
  int find(const std::string& name) const;
};

// Parses BVH text. Throws ks::Error naming `what` and the line for anything malformed: a missing
// HIERARCHY / ROOT / MOTION, an unknown keyword or channel, unbalanced braces, a channel count
// that is not a number, a missing or non-positive Frame Time, a frame line with the wrong number
// of values or a value that is not a finite number, fewer frame lines than "Frames:" says.
Bvh parse_bvh(const std::string& text, const std::string& what);
Bvh read_bvh(const std::string& path);
// BVH text (numbers with 6 decimals for offsets and positions, 6 for angles) and its atomic write.
std::string format_bvh(const Bvh& bvh);
void write_bvh(const std::string& path, const Bvh& bvh);

// Rotation matrix of a rotation channel's angle (degrees).
Eigen::Matrix3d bvh_channel_rotation(BvhChannel c, double degrees);

}  // namespace ks
