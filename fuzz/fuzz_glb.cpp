// libFuzzer harness fuzz_glb: see ks::fuzz::glb in fuzz/targets.hpp.
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ks::fuzz::glb(data, size);
  return 0;
}
