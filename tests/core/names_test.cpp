// core/names.hpp: an enum's value by its name, and the error that lists the names.
#include <gtest/gtest.h>

#include "core/error.hpp"
#include "core/names.hpp"

namespace ks {

namespace {
enum class Colour { kRed, kGreen, kBlue };
const std::vector<std::string> kColours = {"red", "green", "blue"};
}  // namespace

TEST(Names, ParseNameFindsEachValueAndListsTheNamesOtherwise) {
  EXPECT_EQ(parse_name<Colour>(kColours, "red", "colour"), Colour::kRed);
  EXPECT_EQ(parse_name<Colour>(kColours, "blue", "colour"), Colour::kBlue);
  try {
    parse_name<Colour>(kColours, "Red", "colour");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "colour \"Red\": expected red, green or blue");
  }
  EXPECT_THROW(parse_name<Colour>({}, "red", "colour"), Error);
}

}  // namespace ks
