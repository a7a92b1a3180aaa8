#pragma once
// `kinesplat fit SUBJECT --refine-with AVATAR`: the keypoint fit refined photometrically. The
// photo's pose and global transform are registered through the avatar's render
// (register/register.hpp), starting from SUBJECT/fit.json. The keypoint fit is kept beside it
// as SUBJECT/fit_keypoints.json (written once: a second refinement starts from the first's
// result but keeps the original keypoint fit), and the refined fit replaces SUBJECT/fit.json,
// with `costs.registration` saying what changed and `refined_with` naming the avatar.
#include <string>

#include "register/register.hpp"

namespace ks {

struct RefineFitResult {
  RegisterResult registration;
  std::string fit_path, keypoint_fit_path;
};

// Throws ks::Error (naming the file) for a missing or malformed fit.json, image.png or avatar,
// an avatar of another skeleton, or a camera that is not for image.png's size; then nothing is
// written.
RefineFitResult refine_fit(const std::string& subject_dir, const std::string& avatar_path,
                           const RegisterOptions& options = {});

}  // namespace ks
