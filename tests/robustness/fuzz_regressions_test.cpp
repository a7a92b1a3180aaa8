// Replays every input the fuzzers found a bug with (tests/robustness/fuzz_inputs/<harness>/, one
// file each, named after the bug) through the harness's own code (fuzz/targets.hpp): each must now
// load or be refused with a ks::Error. Under `make test-sanitize` this also re-checks them with
// AddressSanitizer and UndefinedBehaviorSanitizer. docs/robustness.md lists them.
#include <gtest/gtest.h>

#include <filesystem>

#include "../../fuzz/targets.hpp"
#include "core/fileio.hpp"

namespace fs = std::filesystem;

namespace ks {
namespace {

TEST(FuzzRegressions, FoundInputsAreClearErrorsNow) {
  const fs::path root = fs::path(KS_SOURCE_DIR) / "tests/robustness/fuzz_inputs";
  size_t replayed = 0;
  for (const auto& dir : fs::directory_iterator(root)) {
    if (!dir.is_directory()) continue;
    const std::string harness = dir.path().filename().string();
    ASSERT_TRUE(fuzz::all_targets().count(harness)) << "no harness " << harness;
    for (const auto& f : fs::directory_iterator(dir.path())) {
      SCOPED_TRACE(f.path().string());
      const std::vector<uint8_t> bytes = read_file_bytes(f.path().string());
      EXPECT_NO_THROW(fuzz::all_targets().at(harness)(bytes.data(), bytes.size()));
      ++replayed;
    }
  }
  EXPECT_GT(replayed, 0u);
}

}  // namespace
}  // namespace ks
