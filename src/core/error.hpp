#pragma once
// Error type for user-facing failures (bad input, missing files, malformed formats).
// The CLI prints what() after "error: " and exits with status 1.
#include <stdexcept>
#include <string>

namespace ks {

struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};

}  // namespace ks
