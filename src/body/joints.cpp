#include "body/joints.hpp"

#include "core/error.hpp"

namespace ks {

const std::vector<int>& smpl_parents() {
  static const std::vector<int> p = {-1, 0, 0, 0,  1,  2,  3,  4,  5,  6,  7,  8,
                                     9,  9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21};
  return p;
}

int first_child(const std::vector<int>& parents, int j) {
  for (size_t c = 0; c < parents.size(); ++c)
    if (parents[c] == j) return int(c);
  return -1;
}

int find_joint(const std::vector<std::string>& names, std::string_view name) {
  for (size_t i = 0; i < names.size(); ++i)
    if (names[i] == name) return int(i);
  return -1;
}

int require_joint(const std::vector<std::string>& names, std::string_view name,
                  const std::string& what) {
  const int j = find_joint(names, name);
  if (j < 0) throw Error(what + ": the body model has no joint named '" + std::string(name) + "'");
  return j;
}

}  // namespace ks
