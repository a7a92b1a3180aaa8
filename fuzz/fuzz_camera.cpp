// libFuzzer harness fuzz_camera: see ks::fuzz::camera in fuzz/targets.hpp.
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ks::fuzz::camera(data, size);
  return 0;
}
