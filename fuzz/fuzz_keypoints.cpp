// libFuzzer harness fuzz_keypoints: see ks::fuzz::keypoints in fuzz/targets.hpp.
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ks::fuzz::keypoints(data, size);
  return 0;
}
