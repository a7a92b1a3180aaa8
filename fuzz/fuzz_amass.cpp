// libFuzzer harness fuzz_amass: see ks::fuzz::amass in fuzz/targets.hpp.
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ks::fuzz::amass(data, size);
  return 0;
}
