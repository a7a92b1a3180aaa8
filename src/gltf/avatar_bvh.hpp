#pragma once
// `kinesplat export AVATAR --bvh OUT.bvh --motion M`: a motion as BVH on the avatar's own
// skeleton (joint names, rest offsets in metres; motion/bvh_motion.hpp poses_to_bvh).
#include "avatar/avatar.hpp"
#include "motion/bvh.hpp"
#include "motion/motion.hpp"

namespace ks {

// The motion's every frame on the avatar's skeleton (avatar_full_pose), at its frame rate.
// Throws ks::Error for an empty motion or a pose the avatar's skeleton cannot take.
Bvh avatar_motion_bvh(const Avatar& avatar, const Motion& motion);

}  // namespace ks
