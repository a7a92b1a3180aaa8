// libFuzzer harness fuzz_avatar: see ks::fuzz::avatar in fuzz/targets.hpp.
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ks::fuzz::avatar(data, size);
  return 0;
}
