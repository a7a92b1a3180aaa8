#pragma once
// An enum's values by name: the one lookup behind every option whose values the CLI, the stages'
// records and the files spell out (the keypoint conventions, the generators, ...).
#include <string>
#include <vector>

#include "core/error.hpp"

namespace ks {

// The value of enum E whose name is `name`, `names` listing them in the enum's order; ks::Error
// ("<what> "<name>": expected a, b or c") for any other name.
template <class E>
E parse_name(const std::vector<std::string>& names, const std::string& name, const char* what) {
  for (size_t i = 0; i < names.size(); ++i)
    if (names[i] == name) return E(i);
  std::string list;
  for (size_t i = 0; i < names.size(); ++i)
    list += (i == 0 ? "" : i + 1 == names.size() ? " or " : ", ") + names[i];
  throw Error(std::string(what) + " \"" + name + "\": expected " + list);
}

}  // namespace ks
