#pragma once
// Environment switches (KS_*_NO_* and the like): set to anything but "" or "0" means on.
#include <cstdlib>

namespace ks {

inline bool env_flag(const char* name) {
  const char* e = std::getenv(name);
  return e != nullptr && e[0] != '\0' && e[0] != '0';
}

}  // namespace ks
