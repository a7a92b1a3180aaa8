// `kinesplat info`: build information.
#include <cstdio>

#include "cli/registry.hpp"

namespace {
ks::cli::CommandGroup group(1000, [](CLI::App& app) {
  auto* sub = app.add_subcommand("info", "Print build information");
  sub->callback([] {
#ifdef __AVX512F__
    const char* isa = "avx512";
#elif defined(__AVX2__)
    const char* isa = "avx2";
#else
    const char* isa = "baseline x86-64";
#endif
    std::printf("kinesplat 0.1.0 (C++20, compiled for %s)\n", isa);
  });
});
}  // namespace
