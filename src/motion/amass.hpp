#pragma once
// AMASS motions (.npz): `poses` (N x 156 SMPL+H, N x 165 SMPL-X, or N x 72 SMPL), `trans` (N x 3),
// `mocap_framerate` (or `mocap_frame_rate`; 30 if absent). Mapped onto SMPL's 24 joints (the 21
// body joints from values 3..65, SMPL's hand joints 22/23 left at zero; the full hands go to
// left/right_hand_pose, SMPL-X's jaw/eyes to jaw/leye/reye_pose) and converted from AMASS's Z-up
// world to kinesplat's Y-up world by a -90 degree rotation about X applied to global_orient and
// trans. The translation is made relative to the first kept frame (the motion starts where the
// rest-pose avatar stands). Frames are subsampled to about 30 fps. Documented in docs/avatar.md.
#include <string>

#include "motion/motion.hpp"

namespace ks {

// frames > 0: keep at most this many frames (after subsampling). Throws ks::Error naming the file
// for a missing key, a wrong shape, non-finite values or an empty motion.
Motion load_amass_npz(const std::string& path, int frames = 0);

// `motion` as an AMASS .npz (poses N x 72, trans N x 3, mocap_framerate; no gender): kinesplat's
// Y-up world turned back to AMASS's Z-up (the inverse of load_amass_npz's rotation). Written
// atomically. Throws ks::Error for an empty motion.
void save_amass_npz(const std::string& path, const Motion& motion);

}  // namespace ks
