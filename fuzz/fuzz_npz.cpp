// libFuzzer harness fuzz_npz: see ks::fuzz::npz in fuzz/targets.hpp.
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ks::fuzz::npz(data, size);
  return 0;
}
