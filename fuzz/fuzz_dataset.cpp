// libFuzzer harness fuzz_dataset: see ks::fuzz::dataset in fuzz/targets.hpp.
#include "targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ks::fuzz::dataset(data, size);
  return 0;
}
