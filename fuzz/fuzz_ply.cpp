// libFuzzer harness fuzz_ply: see ks::fuzz::ply in fuzz/targets.hpp.
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ks::fuzz::ply(data, size);
  return 0;
}
