// The keypoint conventions' names (body/keypoints.hpp): each name parses back to its convention,
// and another name is an error that names it.
#include <gtest/gtest.h>

#include "body/keypoints.hpp"
#include "core/error.hpp"

namespace ks {

TEST(KeypointConventionNames, RoundTripAndUnknownName) {
  ASSERT_EQ(keypoint_convention_names().size(), 2u);
  for (KeypointConvention c : {KeypointConvention::kJoints, KeypointConvention::kCoco})
    EXPECT_EQ(parse_keypoint_convention(to_string(c)), c);
  EXPECT_STREQ(to_string(KeypointConvention::kCoco), "coco");
  try {
    parse_keypoint_convention("openpose");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("\"openpose\""), std::string::npos) << e.what();
  }
}

}  // namespace ks
