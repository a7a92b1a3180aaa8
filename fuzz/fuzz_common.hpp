#pragma once
// Shared by the libFuzzer harnesses (docs/robustness.md): the input is written to a file in a
// per-process temporary directory and handed to the reader exactly as the CLI calls it. The only
// acceptable failure is a ks::Error (which the CLI prints as one `error: ...` line); any other
// exception escapes and libFuzzer reports it, as it does every sanitizer report.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>

#include "core/error.hpp"

namespace ks::fuzz {

// This process's scratch directory (created once, removed at exit).
inline const std::filesystem::path& scratch_dir() {
  static const std::filesystem::path dir = [] {
    auto d = std::filesystem::temp_directory_path() / ("ks-fuzz-" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    static struct Cleanup {
      std::filesystem::path p;
      ~Cleanup() {
        std::error_code ec;
        std::filesystem::remove_all(p, ec);
      }
    } cleanup{d};
    return d;
  }();
  return dir;
}

// Writes the input to scratch_dir()/name and returns its path.
inline std::string input_file(const uint8_t* data, size_t size, const std::string& name) {
  const std::string path = (scratch_dir() / name).string();
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) __builtin_trap();
  if (size) std::fwrite(data, 1, size, f);
  std::fclose(f);
  return path;
}

}  // namespace ks::fuzz

// The body of a harness: `expr` may throw ks::Error; nothing else.
#define KS_FUZZ_EXPECT_ONLY_KS_ERROR(...) \
  do {                                    \
    try {                                 \
      __VA_ARGS__;                        \
    } catch (const ks::Error&) {          \
    }                                     \
  } while (0)
