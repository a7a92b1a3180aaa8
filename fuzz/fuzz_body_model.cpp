// libFuzzer harness fuzz_body_model: see ks::fuzz::body_model in fuzz/targets.hpp.
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ks::fuzz::body_model(data, size);
  return 0;
}
