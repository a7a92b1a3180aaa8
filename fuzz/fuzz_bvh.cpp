// libFuzzer harness fuzz_bvh: see ks::fuzz::bvh in fuzz/targets.hpp.
#include "targets.hpp"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  (void)ks::default_body_model();  // built once (slow under the sanitizers), not in the first unit
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ks::fuzz::bvh(data, size);
  return 0;
}
