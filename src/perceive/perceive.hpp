#pragma once
// `kinesplat perceive`: one photo in, a subject folder out:
//   SUBJECT/image.png       the photo upright (EXIF), downscaled so its longer side <= max_size,
//                           RGB (an alpha channel goes to the mask), bit depth kept
//   SUBJECT/mask.png        8-bit, 255 = person, 0 = not, image.png's size
//   SUBJECT/keypoints.json  OpenPose layout: people[0].pose_keypoints_2d (BODY_25, 25 x (x, y,
//                           conf)) in image.png's pixels, pixel centres at integer + 0.5;
//                           face_keypoints_2d (OpenPose's 70) when there are face landmarks
//   SUBJECT/perceive.json   where each part came from, the scale source -> image.png, times
//   SUBJECT/perceive_overlay.png  with PerceiveOptions::overlay: keypoints and mask on the photo
// The user's own keypoints and mask win; the built-in detector (helpers/perceive) gives the rest.
// Written atomically: on any error nothing is written.
#include <string>
#include <vector>

#include "core/image.hpp"
#include "perceive/openpose.hpp"

namespace ks {

struct PerceiveOptions {
  int max_size = 1024;         // longer side of image.png (0: keep the photo's size)
  std::string keypoints_path;  // the user's OpenPose / COCO keypoint JSON (in the photo's pixels)
  std::string mask_path;       // the user's mask image (the photo's size)
  double keypoints_pixel_centre = 0.0;  // see KeypointReadOptions (0: OpenPose/COCO, 0.5: ours)
  float min_keypoint_score = 0.3f;      // detector keypoints below this score are written as absent
  // The heels and big toes (the foot index) from BlazePose's landmarks where their visibility is
  // at least this (MoveNet's 17 points have no feet); 0 or less: none. Off by default: on synth
  // seeds 0-14 they moved the fit's median PA-MPJPE from 18.7 to 19.1 mm (0-9) and 18.5 to 20.4 mm
  // (10-14) with 0.5, better on some people and worse on others (docs/fit.md).
  float min_foot_visibility = 0.0f;
  // The detector's segmentation is a 256 x 256 map stretched over the person (about 3 photo pixels
  // per cell for a person filling a 768-pixel image): it fills narrow gaps (armpits) and blurs the
  // outline. A guided filter with the photo as guide carries it onto the photo's edges: window
  // radius in cells of that map, regularisation eps (chosen on the sample photo ryota.png against
  // its own mask: IoU 0.971 -> 0.992).
  bool refine_mask = true;
  double refine_radius_cells = 2.0;
  double refine_eps = 1e-3;
  float mask_threshold = 0.5f;  // detector segmentation probability that counts as person
  // An alpha channel is the mask only when between this share and 1 - it of its pixels are opaque.
  double min_alpha_share = 0.01;
  int min_person_size = 64;  // the person's longer side in image.png, pixels
  bool face = true;          // face landmarks from the detector when the keypoints lack them
  bool overlay = false;      // also write SUBJECT/perceive_overlay.png (perceive_overlay())
  std::string helper_dir;    // empty: find_perceive_helper()
  double helper_timeout_s = 300;
};

struct PerceiveReport {
  std::string out_dir;
  int width = 0, height = 0;  // image.png
  int source_width = 0, source_height = 0;
  std::string keypoints_source;  // "user" or "detector"
  std::string mask_source;       // "user", "alpha" or "detector"
  bool face = false;             // face_keypoints_2d written
  int people = 0;                // people the detector found (0 when it did not run)
  int body_keypoints = 0;        // present BODY_25 keypoints
  double seconds = 0;
  std::vector<std::string> notes;  // warnings and what was skipped
};

// Runs perceive on `photo`, writing `out_dir` (replaced when it is an earlier perceive output;
// refused when it is another non-empty folder). Throws ks::Error (and writes nothing) when the
// photo cannot be read, no person is found, the person is smaller than min_person_size, the
// detector is needed but not installed, or the user's files are malformed.
PerceiveReport run_perceive(const std::string& photo, const std::string& out_dir,
                            const PerceiveOptions& opts = {});

class PerceiveHelper;

// The same with a detector helper the caller started (find_perceive_helper, PerceiveHelper) and
// keeps warm across photos (`track`); it is asked only for what the user's files leave out.
PerceiveReport run_perceive(const std::string& photo, const std::string& out_dir,
                            const PerceiveOptions& opts, PerceiveHelper& helper);

// A detector's answer turned into BODY_25 (in the detector's pixel convention, which is ours):
// COCO-17 keypoints [x, y, score] -> BODY_25 with scores below `min_score` absent.
Body25 body25_from_detector(const std::vector<std::array<double, 3>>& coco17, float min_score);

// BlazePose's heel and foot-index landmarks (33 landmarks [x, y, visibility, presence]) as
// BODY_25's heels and big toes, each side where both are visible at least `min_visibility`, the
// side's ankle is in `body` and BlazePose's own ankle agrees with it (within the foot's length:
// a side BlazePose swapped is left out); confidence = the visibility. Returns how many points
// were added.
int body25_add_feet(Body25& body, const std::vector<std::array<double, 4>>& blazepose,
                    float min_visibility);

}  // namespace ks
