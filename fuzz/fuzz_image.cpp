// libFuzzer harness fuzz_image: see ks::fuzz::image in fuzz/targets.hpp.
#include "targets.hpp"

#include <cstdlib>

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  // Keep the decoders' allocations small while fuzzing: OpenCV refuses images over 4 Mpx (its
  // default is 2^30 pixels; kinesplat's own check, kMaxImagePixels, is 2^27).
  setenv("OPENCV_IO_MAX_IMAGE_PIXELS", "4194304", 1);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ks::fuzz::image(data, size);
  return 0;
}
