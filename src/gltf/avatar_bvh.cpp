#include "gltf/avatar_bvh.hpp"

#include "avatar/pose.hpp"
#include "core/error.hpp"
#include "motion/bvh_motion.hpp"

namespace ks {

Bvh avatar_motion_bvh(const Avatar& a, const Motion& m) {
  if (m.frames.empty()) throw Error("bvh: motion \"" + m.name + "\" has no frames");
  std::vector<Eigen::MatrixXd> poses;
  std::vector<Eigen::Vector3d> transl;
  for (const BodyParams& p : m.frames) {
    poses.push_back(avatar_full_pose(a, p));
    transl.push_back(p.transl);
  }
  std::vector<std::string> names = a.joint_names;
  if (names.size() != a.parents.size()) {
    names.clear();
    for (size_t j = 0; j < a.parents.size(); ++j) names.push_back("joint_" + std::to_string(j));
  }
  return poses_to_bvh(a.parents, names, a.rest_joints, poses, transl, m.fps);
}

}  // namespace ks
