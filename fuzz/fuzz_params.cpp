// libFuzzer harness fuzz_params: see ks::fuzz::params in fuzz/targets.hpp.
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ks::fuzz::params(data, size);
  return 0;
}
