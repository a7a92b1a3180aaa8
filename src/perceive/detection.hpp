#pragma once
// One request to the detector helper (helpers/perceive, through PerceiveHelper): the image handed
// over in a private temporary folder, the answer checked and read (COCO-17 keypoints, the
// segmentation's person probability, BlazePose's 33 landmarks, the face mesh). Used by run_perceive
// (docs/perceive.md).
#include <array>
#include <nlohmann/json.hpp>
#include <vector>

#include "core/image.hpp"
#include "perceive/helper.hpp"
#include "perceive/perceive.hpp"

namespace ks {

// The detector's answer for one image, checked.
struct Detection {
  nlohmann::json response;
  std::vector<std::array<double, 3>> coco17;
  Image mask_prob;  // 1 channel probability, image size
  std::vector<std::array<double, 2>> face_mesh;
  double face_score = 0;
  // BlazePose's 33 body landmarks (x, y, visibility, presence; pixels and probabilities), or
  // none where the answer has no such list.
  std::vector<std::array<double, 4>> blazepose;
};

// Runs the detector on `rgb` (`photo` names the photo in errors). Throws ks::Error when it finds
// no person or fails, and when its answer is malformed.
Detection run_detector(PerceiveHelper& helper, const Image& rgb, const std::string& photo,
                       const PerceiveOptions& opts);

}  // namespace ks
