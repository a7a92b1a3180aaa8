// The generators' names (generate/generate.hpp): each name parses back to its generator, and
// another name is an error that names it.
#include <gtest/gtest.h>

#include "core/error.hpp"
#include "generate/generate.hpp"

namespace ks {

TEST(GeneratorNames, RoundTripAndUnknownName) {
  ASSERT_EQ(generator_names().size(), 3u);
  for (Generator g : {Generator::kLift, Generator::kCommand, Generator::kFrames})
    EXPECT_EQ(parse_generator(to_string(g)), g);
  EXPECT_STREQ(to_string(Generator::kLift), "lift");
  try {
    parse_generator("diffusion");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("\"diffusion\""), std::string::npos) << e.what();
  }
}

}  // namespace ks
